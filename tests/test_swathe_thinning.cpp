// Density thinning (SceneSwathe::ThinByImageDensity, CalibrationOptions::thin_*):
// a crowded image cell keeps about the cap of its points, sparse points stay,
// points beyond the margin outside the image or behind the camera go, and the
// choice is a fixed function of the scene. Synthetic swathe: lidar = camera
// (identity extrinsic), two scans at the image's pose.
#include <algorithm>
#include <set>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/calibrate.hpp"
#include "core/swathe.hpp"
#include "support/random_swathe.hpp"

namespace scenecal {
namespace {

constexpr int kCrowdPerScan = 200;  // points of each scan that land in one 4 x 4 pixel cell
constexpr int kSparse = 10;         // points in ten different cells
constexpr int kCellPx = 4;
constexpr double kMarginPx = 20.0;

CameraInfo MakeCamera() {
  CameraInfo camera;
  camera.name = "cam";
  camera.model = test::MakeKernelTestCamera(CameraModelKind::kPinhole);  // 320 x 240
  return camera;
}

// A camera-frame point at depth z (m) that projects to pixel (u, v) of MakeCamera.
LidarPoint AtPixel(double u, double v, double z, float reflectance) {
  const Eigen::Vector3d p = MakeCamera().model.Unproject(Eigen::Vector2d(u, v)) * z;
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), reflectance};
}

SceneSwathe MakeSwathe(std::vector<LidarScan>* scans_storage) {
  const CameraInfo camera = MakeCamera();
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.image_t_us = 123456;
  scans_storage->assign(2, LidarScan{});
  float id = 0.0f;  // distinct reflectances: every point can be told apart after rank normalisation
  for (int j = 0; j < 2; ++j) {
    LidarScan& scan = (*scans_storage)[j];
    scan.t_us = 1000 * (j + 1);
    SwatheScan swathe_scan;
    swathe_scan.t_us = scan.t_us;
    scene.scans.push_back(swathe_scan);  // identity T_basek_basej: the image's own pose
    for (int k = 0; k < kCrowdPerScan; ++k) {
      const double offset = 0.001 * (k + kCrowdPerScan * j);  // 40.0 .. 40.4: one cell
      scan.points.push_back(AtPixel(40.0 + offset, 30.0 + offset, 5.0, id += 1.0f));
    }
  }
  for (int k = 0; k < kSparse; ++k) {
    (*scans_storage)[0].points.push_back(AtPixel(90.0 + 6.0 * k, 90.0, 5.0, id += 1.0f));
  }
  LidarScan& second = (*scans_storage)[1];
  second.points.push_back(AtPixel(-10.0, 60.0, 5.0, id += 1.0f));  // outside the image, within the margin: kept
  second.points.push_back(AtPixel(-40.0, 60.0, 5.0, id += 1.0f));  // beyond the margin: dropped
  second.points.push_back({0.0f, 0.0f, -5.0f, id += 1.0f});         // behind the camera: dropped

  cv::Mat image(camera.model.height, camera.model.width, CV_32FC1);
  cv::randu(image, 0.0f, 1.0f);
  std::vector<const LidarScan*> scans{&(*scans_storage)[0], &(*scans_storage)[1]};
  return SceneSwathe::Build(scene, camera, image, scans, SwatheOptions{}, NormalisationOptions{});
}

using Projected = std::tuple<float, float, float>;  // u, v, reflectance01

std::vector<Projected> AllProjected(const SceneSwathe& swathe) {
  std::vector<Projected> points;
  swathe.ForEachProjected(Eigen::Isometry3d::Identity(), false,
                          [&](std::size_t, float x01, float u, float v, float) { points.emplace_back(u, v, x01); });
  return points;
}

TEST(SwatheThinning, CrowdedCellKeepsAboutTheCapAndSparsePointsStay) {
  std::vector<LidarScan> storage;
  SceneSwathe swathe = MakeSwathe(&storage);
  ASSERT_EQ(swathe.PointCount(), 2u * kCrowdPerScan + kSparse + 3u);
  const std::vector<Projected> before = AllProjected(swathe);

  const int cap = 5;
  const std::size_t kept =
      swathe.ThinByImageDensity(MakeCamera().model, Eigen::Isometry3d::Identity(), kCellPx, cap, kMarginPx);
  EXPECT_EQ(kept, swathe.PointCount());
  const std::vector<Projected> after = AllProjected(swathe);
  // In the image: the sparse points and what is left of the crowd; the point
  // within the margin is kept but does not project into the image.
  const std::size_t crowd_kept = after.size() - kSparse;
  EXPECT_EQ(kept, after.size() + 1);
  EXPECT_GE(crowd_kept, 1u);
  EXPECT_LE(crowd_kept, 15u);  // expectation 5 of 400 (binomial, sd ~2.2)
  EXPECT_LT(crowd_kept, 2u * kCrowdPerScan);

  // Every kept point is one of the originals, unchanged (position and reflectance).
  const std::set<Projected> original(before.begin(), before.end());
  for (const Projected& p : after) EXPECT_TRUE(original.count(p)) << std::get<0>(p) << ", " << std::get<1>(p);
  // All ten sparse points (v = 90) are among them.
  EXPECT_EQ(std::count_if(after.begin(), after.end(), [](const Projected& p) { return std::get<1>(p) > 80.0f; }),
            kSparse);
  // The scan structure is kept: per-scan counts add up, the sparse points are in scan 0.
  const std::vector<std::size_t> per_scan = swathe.CountProjectedPerScan(Eigen::Isometry3d::Identity());
  ASSERT_EQ(per_scan.size(), 2u);
  EXPECT_EQ(per_scan[0] + per_scan[1], after.size());
  EXPECT_GE(per_scan[0], static_cast<std::size_t>(kSparse));
}

TEST(SwatheThinning, IsDeterministicAndOffAtCapZero) {
  std::vector<LidarScan> storage_a, storage_b, storage_c;
  SceneSwathe a = MakeSwathe(&storage_a), b = MakeSwathe(&storage_b), c = MakeSwathe(&storage_c);
  const CameraModel camera = MakeCamera().model;
  a.ThinByImageDensity(camera, Eigen::Isometry3d::Identity(), kCellPx, 5, kMarginPx);
  b.ThinByImageDensity(camera, Eigen::Isometry3d::Identity(), kCellPx, 5, kMarginPx);
  EXPECT_EQ(AllProjected(a), AllProjected(b));

  const std::size_t all = c.PointCount();
  EXPECT_EQ(c.ThinByImageDensity(camera, Eigen::Isometry3d::Identity(), kCellPx, 0, kMarginPx), all);
  EXPECT_EQ(c.PointCount(), all);
  // A camera model of another size leaves the swathe whole.
  CameraModel other = camera;
  other.width = 640;
  EXPECT_EQ(c.ThinByImageDensity(other, Eigen::Isometry3d::Identity(), kCellPx, 5, kMarginPx), all);
}

TEST(SwatheThinning, ALargeCapDropsOnlyPointsBeyondTheMarginOrBehind) {
  std::vector<LidarScan> storage;
  SceneSwathe swathe = MakeSwathe(&storage);
  const std::size_t all = swathe.PointCount();
  EXPECT_EQ(swathe.ThinByImageDensity(MakeCamera().model, Eigen::Isometry3d::Identity(), kCellPx, 1000, kMarginPx),
            all - 2);
  // With the estimate moved so that the crowd leaves the grown image, it is dropped too.
  std::vector<LidarScan> storage_moved;
  SceneSwathe moved = MakeSwathe(&storage_moved);
  Eigen::Isometry3d shifted = Eigen::Isometry3d::Identity();
  // u of the crowd (depth 5 m) -> 40 - (45 + margin) = -25: beyond the margin.
  shifted.translation().x() = -5.0 * (40.0 + kMarginPx + 5.0) / MakeCamera().model.fx;
  const std::size_t kept = moved.ThinByImageDensity(MakeCamera().model, shifted, kCellPx, 1000, kMarginPx);
  EXPECT_EQ(kept, static_cast<std::size_t>(kSparse));  // the sparse points move to u = 25 .. 79 and stay
}

TEST(SwatheThinning, CalibrationOptionsRefuseBadThinningSettings) {
  CalibrationOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.thin_max_points_per_cell = -1;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("thin_max_points_per_cell"), std::string::npos);
  options = CalibrationOptions{};
  options.thin_cell_px = 0;
  EXPECT_FALSE(options.IsValid(&why));
  options = CalibrationOptions{};
  options.thin_margin_px = -1.0;
  EXPECT_FALSE(options.IsValid(&why));
}

}  // namespace
}  // namespace scenecal
