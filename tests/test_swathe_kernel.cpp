// The fast kernels of SceneSwathe against the reference paths they replace:
// - ProjectAnyBlock (run-time dispatched AVX2 / SSE2 clone, vectorised) gives
//   the same pixels, bit for bit, and the same accept decisions as ProjectFast;
// - AddHardCounts gives the same hard count table, bin for bin, as the
//   ForEachProjected visitor + BilinearSampler + HardBin path of
//   PairCost::SceneCost, for every camera model, bin counts, blur, occlusion,
//   on a non-finite image (generic fallback), and on a real OpenCalib frame.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry.hpp"
#include "core/metric.hpp"
#include "core/normalisation.hpp"
#include "core/swathe.hpp"
#include "io/opencalib.hpp"
#include "io/pcd.hpp"
#include "support/random_swathe.hpp"

namespace scenecal {
namespace {

using test::TestSwathe;

CameraModel MakeCamera(CameraModelKind kind) { return test::MakeKernelTestCamera(kind); }

// A swathe of 5 random scans over an image of uniform noise.
TestSwathe MakeSwathe(CameraModelKind kind, std::uint32_t seed) {
  const CameraModel camera = MakeCamera(kind);
  cv::Mat image(camera.height, camera.width, CV_32FC1);
  cv::randu(image, 0.0f, 1.0f);
  return test::MakeRandomSwathe(camera, image, seed);
}

std::vector<std::uint32_t> VisitorCounts(const SceneSwathe& swathe, const Eigen::Isometry3d& T, int nx, int ny,
                                         std::size_t* samples) {
  std::vector<std::uint32_t> counts(static_cast<std::size_t>(nx * ny), 0u);
  const SceneSwathe::BilinearSampler sample = swathe.Sampler();
  *samples = 0;
  swathe.ForEachProjected(T, true, [&](std::size_t, float x01, float u, float v, float) {
    ++counts[static_cast<std::size_t>(HardBin(x01, nx) * ny + HardBin(sample(u, v), ny))];
    ++*samples;
  });
  return counts;
}

// Compares AddHardCounts with the visitor path at T; returns the samples compared.
std::size_t ExpectSameCounts(const SceneSwathe& swathe, const Eigen::Isometry3d& T, int nx, int ny) {
  std::size_t expected_samples = 0;
  const std::vector<std::uint32_t> expected = VisitorCounts(swathe, T, nx, ny, &expected_samples);
  std::vector<std::uint32_t> counts(expected.size(), 7u);  // added to, not cleared
  const std::size_t samples = swathe.AddHardCounts(T, nx, ny, counts.data());
  EXPECT_EQ(samples, expected_samples);
  int differing = 0;
  for (std::size_t i = 0; i < counts.size(); ++i) differing += counts[i] != expected[i] + 7u;
  EXPECT_EQ(differing, 0) << "bins of " << nx << " x " << ny;
  return samples;
}

std::vector<Eigen::Isometry3d> TestPoses() {
  std::vector<Eigen::Isometry3d> poses = {Eigen::Isometry3d::Identity()};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int i = 0; i < 6; ++i) {
    Vector6d delta;
    for (int k = 0; k < 6; ++k) delta(k) = noise(rng) * (k < 3 ? 0.05 : RadiansFromDegrees(2.0));
    poses.push_back(ExpSE3(delta));
  }
  return poses;
}

TEST(SwatheKernel, ProjectAnyBlockMatchesProjectFastBitForBit) {
  for (const CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
    const ProjectionParams params = MakeProjectionParams(MakeCamera(kind), 0.5, 0.2);
    std::mt19937 rng(11);
    const LidarScan scan = test::RandomFrustumScan(rng, swathe_detail::kBlock);
    std::vector<float> x, y, z;
    std::vector<std::uint8_t> visible;
    for (const LidarPoint& p : scan.points) {
      x.push_back(p.x);
      y.push_back(p.y);
      z.push_back(p.z);
      visible.push_back(static_cast<std::uint8_t>(x.size() % 5 != 0));  // every 5th hidden
    }
    Vector6d tuple;
    tuple << 0.1, -0.2, 0.3, 0.02, -0.03, 0.01;
    const Eigen::Matrix<float, 3, 4> m = TransformFromTuple(tuple).matrix().topRows<3>().cast<float>();
    std::vector<float> u(x.size()), v(x.size()), depth(x.size());
    std::vector<std::int32_t> accepted(x.size());
    const int count = static_cast<int>(x.size()) - 3;  // a partial block
    swathe_detail::ProjectAnyBlock(params, m, x.data(), y.data(), z.data(), visible.data(), count, u.data(), v.data(),
                                   depth.data(), accepted.data());
    int accepted_points = 0;
    for (int k = 0; k < count; ++k) {
      const float px = m(0, 0) * x[k] + m(0, 1) * y[k] + m(0, 2) * z[k] + m(0, 3);
      const float py = m(1, 0) * x[k] + m(1, 1) * y[k] + m(1, 2) * z[k] + m(1, 3);
      const float pz = m(2, 0) * x[k] + m(2, 1) * y[k] + m(2, 2) * z[k] + m(2, 3);
      float u_fast = 0.0f, v_fast = 0.0f;
      const bool expected = ProjectFast(params, px, py, pz, &u_fast, &v_fast) && visible[k] != 0;
      ASSERT_EQ(accepted[k] != 0, expected) << "point " << k;
      if (!expected) continue;
      ++accepted_points;
      EXPECT_EQ(u[k], u_fast) << "point " << k;
      EXPECT_EQ(v[k], v_fast) << "point " << k;
      EXPECT_EQ(depth[k], pz) << "point " << k;
    }
    EXPECT_GT(accepted_points, count / 4);  // the test points mostly project
    EXPECT_LT(accepted_points, count);      // and some do not
  }
}

TEST(SwatheKernel, AddHardCountsMatchesTheVisitorPathForEveryCameraModelBinsAndBlur) {
  for (const CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
    TestSwathe t = MakeSwathe(kind, 5);
    ASSERT_GT(t.swathe.PointCount(), 0u);
    std::size_t compared = 0;
    for (const double blur_px : {0.0, 1.7}) {
      t.swathe.SetImageBlur(blur_px);
      for (const Eigen::Isometry3d& T : TestPoses()) {
        compared += ExpectSameCounts(t.swathe, T, 32, 32);
        compared += ExpectSameCounts(t.swathe, T, 7, 13);
        compared += ExpectSameCounts(t.swathe, T, 2, HistogramOptions::kMaxBins);
      }
    }
    EXPECT_GT(compared, 10000u) << CameraModelKindName(kind);
  }
}

TEST(SwatheKernel, AddHardCountsCountsVisiblePointsOnly) {
  TestSwathe t = MakeSwathe(CameraModelKind::kPinhole, 9);
  const std::size_t before = t.swathe.VisibleCount();
  t.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), SwatheOptions{});
  ASSERT_LT(t.swathe.VisibleCount(), before);  // random points hide one another
  std::vector<std::uint32_t> counts(32 * 32, 0u);
  const std::size_t samples = t.swathe.AddHardCounts(Eigen::Isometry3d::Identity(), 32, 32, counts.data());
  EXPECT_EQ(samples, t.swathe.CountProjected(Eigen::Isometry3d::Identity()));
  for (const Eigen::Isometry3d& T : TestPoses()) ExpectSameCounts(t.swathe, T, 32, 32);
}

// A blurred stage's point stride: every k-th point scored, the scene's count
// of projected points (which decides whether it is used) unchanged, the stride
// kept across refreshes, and the sharp stage's mask and cost restored exactly.
TEST(SwatheKernel, ABlurredStageScoresEveryKthPointAndTheSharpStageAllAgain) {
  EXPECT_EQ(PointStrideForBlur(25.6, 8.0), 3);
  EXPECT_EQ(PointStrideForBlur(7.9, 8.0), 1);
  EXPECT_EQ(PointStrideForBlur(0.0, 8.0), 1);
  EXPECT_EQ(PointStrideForBlur(25.6, 0.0), 1);  // 0: every point
  TestSwathe t = MakeSwathe(CameraModelKind::kPinhole, 9);
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  t.swathe.RefreshVisibility(T, SwatheOptions{});
  const std::size_t visible = t.swathe.VisibleCount(), projected = t.swathe.CountProjected(T);
  ASSERT_GT(projected, 1000u);
  const auto cost_at = [&](const Eigen::Isometry3d& pose) {
    JointHistogram histogram(HistogramOptions{32, 32, Binning::kBSpline});
    const std::size_t added = t.swathe.AddBSplineSamples(pose, &histogram);
    return std::make_pair(added, CostValue(ComputeInformation(histogram), MetricKind::kNid));
  };
  const auto [sharp_added, sharp_cost] = cost_at(T);
  EXPECT_EQ(sharp_added, projected);
  t.swathe.SetImageBlur(24.0, 3);
  const std::size_t strided = t.swathe.VisibleCount();
  EXPECT_GE(strided, visible / 3 - 50);
  EXPECT_LE(strided, visible / 3 + 50);
  EXPECT_EQ(t.swathe.CountProjected(T), projected);  // the scene's count is the unstrided one
  const std::size_t blurred_added = cost_at(T).first;
  EXPECT_GE(blurred_added, projected / 3 - 50);
  EXPECT_LE(blurred_added, projected / 3 + 50);
  t.swathe.RefreshVisibility(T, SwatheOptions{});  // a refresh within the stage keeps its stride
  EXPECT_EQ(t.swathe.VisibleCount(), strided);
  t.swathe.SetImageBlur(24.0, 4);  // a new stride starts from the whole mask
  EXPECT_GE(t.swathe.VisibleCount(), visible / 4 - 50);
  EXPECT_LE(t.swathe.VisibleCount(), visible / 4 + 50);
  t.swathe.SetImageBlur(0.0);
  EXPECT_EQ(t.swathe.VisibleCount(), visible);
  const auto [again_added, again_cost] = cost_at(T);
  EXPECT_EQ(again_added, sharp_added);
  EXPECT_EQ(again_cost, sharp_cost);
}

TEST(SwatheKernel, AddHardCountsOnANonFiniteImageTakesTheGenericPath) {
  CameraInfo camera;
  camera.name = "cam";
  camera.model = MakeCamera(CameraModelKind::kPinhole);
  cv::Mat image(camera.model.height, camera.model.width, CV_32FC1);
  cv::randu(image, 0.0f, 1.0f);
  // NaN and infinite pixels: HardBin puts NaN samples in bin 0 (and infinities at the ends).
  for (int v = 0; v < image.rows; v += 3) image.at<float>(v, v % image.cols) = std::numeric_limits<float>::quiet_NaN();
  for (int v = 1; v < image.rows; v += 5) image.at<float>(v, (3 * v) % image.cols) = std::numeric_limits<float>::infinity();
  std::mt19937 rng(21);
  const LidarScan scan = test::RandomFrustumScan(rng, 3000);
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.scans.push_back({0, Eigen::Isometry3d::Identity()});
  const SceneSwathe swathe =
      SceneSwathe::Build(scene, camera, image, {&scan}, SwatheOptions{}, NormalisationOptions{});
  ASSERT_GT(swathe.PointCount(), 0u);
  for (const Eigen::Isometry3d& T : TestPoses()) ExpectSameCounts(swathe, T, 32, 32);
}

// The real OpenCalib frame 1 (1920x1200 radtan camera, real image and sweep),
// repeated as a swathe of 6 scans under small relative poses, as in bench_cost.
TEST(SwatheKernel, AddHardCountsMatchesTheVisitorPathOnARealFrame) {
  const std::filesystem::path dir = std::filesystem::path(SCENECAL_SHARED_DATA_DIR) / "opencalib" / "1";
  if (!std::filesystem::exists(dir / "calib.txt")) GTEST_SKIP() << "no OpenCalib data at " << dir;
  const io::OpenCalibCalibration calibration = io::ReadOpenCalibCalibration(dir / "calib.txt");
  const cv::Mat grey = cv::imread((dir / "calib.jpg").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(grey.empty());
  cv::Mat intensity;
  grey.convertTo(intensity, CV_32F, 1.0 / 255.0);
  CameraInfo camera;
  camera.name = "cam";
  camera.model = io::OpenCalibCameraModel(calibration, grey.cols, grey.rows);
  LidarScan sweep;
  for (const LidarPoint& p : io::ReadPcd(dir / "calib.pcd").points) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) sweep.points.push_back(p);
  }
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  std::vector<const LidarScan*> scans;
  for (int j = 0; j < 6; ++j) {
    Vector6d tuple;
    tuple << 0.01 * j, 0.0, 0.03 * j, 0.0, RadiansFromDegrees(0.1 * j), 0.0;
    scene.scans.push_back({j, TransformFromTuple(tuple)});
    scans.push_back(&sweep);
  }
  SceneSwathe swathe = SceneSwathe::Build(scene, camera, intensity, scans, SwatheOptions{}, NormalisationOptions{});
  swathe.RefreshVisibility(calibration.T_camera_lidar, SwatheOptions{});
  std::size_t compared = 0;
  for (const double blur_px : {0.0, 7.68, 2.88}) {  // the default stages' blurs: 0.004 and 0.0015 of 1920 px
    swathe.SetImageBlur(blur_px);
    for (const Eigen::Isometry3d& delta : TestPoses()) {
      compared += ExpectSameCounts(swathe, delta * calibration.T_camera_lidar, 32, 32);
      compared += ExpectSameCounts(swathe, delta * calibration.T_camera_lidar, 8, 8);
    }
  }
  EXPECT_GT(compared, 100000u);
}

// With an intensity high-pass the sharp (final-stage) image is the high-passed
// one and a blurred stage blurs the whole image, not the high-passed one.
TEST(SwatheImage, HighPassIsTheSharpImageAndBlurStartsFromTheWholeImage) {
  const CameraModel camera = test::MakeKernelTestCamera(CameraModelKind::kPinhole);
  cv::Mat image(camera.height, camera.width, CV_32FC1);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      image.at<float>(r, c) = 0.1f + 0.7f * static_cast<float>(c) / static_cast<float>(image.cols) +
                              (((r / 3 + c / 3) % 2 == 0) ? 0.08f : -0.08f);
    }
  }
  test::TestSwathe t = test::MakeRandomSwathe(camera, image, 7);
  NormalisationOptions highpass;
  highpass.intensity_highpass_width_fraction = 0.05;  // sigma 16 px on the 320 px image
  std::vector<const LidarScan*> scans;
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  for (std::size_t j = 0; j < t.scans.size(); ++j) {
    scene.scans.push_back({static_cast<TimeUs>(j), Eigen::Isometry3d::Identity()});
    scans.push_back(&t.scans[j]);
  }
  SceneSwathe swathe = SceneSwathe::Build(scene, t.camera, image, scans, SwatheOptions{}, highpass);
  ASSERT_GT(swathe.PointCount(), 0u);
  const cv::Mat expected_sharp = HighPassImage(image, 0.05 * camera.width);
  cv::Mat expected_blurred;
  cv::GaussianBlur(image, expected_blurred, cv::Size(0, 0), 2.5, 2.5, cv::BORDER_REFLECT);
  const std::vector<cv::Point> pixels = {{40, 30}, {160, 120}, {161, 120}, {290, 200}};
  const auto expect_image = [&](const cv::Mat& expected, const char* what) {
    for (const cv::Point& p : pixels) {
      EXPECT_NEAR(swathe.Sample(static_cast<float>(p.x), static_cast<float>(p.y)), expected.at<float>(p), 1e-5)
          << what << " at " << p;
    }
  };
  expect_image(expected_sharp, "sharp (high-passed)");
  swathe.SetImageBlur(2.5);
  expect_image(expected_blurred, "blurred whole image");
  swathe.SetImageBlur(0.0);
  expect_image(expected_sharp, "sharp again");
  // The two differ where the ramp is: the high-pass drops the region's brightness.
  EXPECT_GT(std::abs(expected_sharp.at<float>(120, 290) - expected_blurred.at<float>(120, 290)), 0.1f);
  // Without the option the sharp image is the image itself.
  EXPECT_NEAR(t.swathe.Sample(290.0f, 200.0f), image.at<float>(200, 290), 1e-6);
}

}  // namespace
}  // namespace scenecal
