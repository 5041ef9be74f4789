// Swathe trimming (CalibrationOptions::swathe_trim_margin_m): a scene keeps
// only the scans whose points reach the image at the initial guess, plus a
// margin of travel either side; SceneSwathe::CountProjectedPerScan says which
// scans reach it. Synthetic scene: the vehicle drives forward along the
// camera's z axis and every scan holds points 3 m behind the lidar, so a scan
// reaches the image only once the vehicle has travelled more than ~3.2 m.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/calibrate.hpp"

namespace scenecal {
namespace {

constexpr double kPointsBehindLidarM = 3.0;  // lidar frame z of every point (m)
constexpr double kScanSpacingM = 0.5;        // travel between scans (m)
constexpr int kScans = 21;                   // travel 0 .. 10 m

CalibrationInput MakeInput() {
  CalibrationInput input;
  CameraInfo camera;
  camera.name = "cam";
  camera.model.width = 160;
  camera.model.height = 120;
  camera.model.fx = camera.model.fy = 100.0;
  camera.model.cx = 80.0;
  camera.model.cy = 60.0;
  input.rig.base_frame = "cam";
  input.rig.cameras.push_back(camera);
  LidarInfo lidar;
  lidar.name = "lidar";
  input.rig.lidars.push_back(lidar);  // at the camera, axes aligned (initial guess = identity)

  cv::Mat image(120, 160, CV_32FC1);
  cv::randu(image, 0.0f, 1.0f);
  input.images["cam"][0] = GreyImage{0, image};

  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  scene.image_t_us = 0;
  for (int j = 0; j < kScans; ++j) {
    const TimeUs t = 1000 * (j + 1);
    SwatheScan swathe_scan;
    swathe_scan.t_us = t;
    swathe_scan.T_basek_basej.translation() = Eigen::Vector3d(0.0, 0.0, kScanSpacingM * j);  // driving along z
    scene.scans.push_back(swathe_scan);
    LidarScan scan;
    scan.t_us = t;
    for (int i = 0; i < 50; ++i) {
      // A narrow row (|x| <= 5 cm): inside the image at any depth beyond min_depth_m.
      const float x = -0.05f + 0.002f * static_cast<float>(i);
      scan.points.push_back({x, 0.02f, static_cast<float>(-kPointsBehindLidarM), static_cast<float>(i % 7) / 7.0f});
    }
    input.scans["lidar"][t] = scan;
  }
  input.selection.scenes.push_back(scene);
  return input;
}

// Travel of the first scan whose points are in front of the camera (depth > min_depth_m).
double FirstReachingTravel(const CalibrationOptions& options) {
  for (int j = 0; j < kScans; ++j) {
    if (kScanSpacingM * j - kPointsBehindLidarM > options.cost.swathe.min_depth_m) return kScanSpacingM * j;
  }
  return 1e9;
}

TEST(SwatheTrim, CountProjectedPerScanSplitsTheCountByScan) {
  const CalibrationInput input = MakeInput();
  CalibrationOptions options;
  options.swathe_trim_margin_m = -1.0;  // whole window
  const PairCost pair = BuildPairCost(input, input.rig.cameras[0], "lidar", options);
  ASSERT_EQ(pair.SceneCount(), 1);
  const SceneSwathe& swathe = pair.Scenes()[0];
  ASSERT_EQ(swathe.ScanCount(), static_cast<std::size_t>(kScans));
  const std::vector<std::size_t> per_scan = swathe.CountProjectedPerScan(Eigen::Isometry3d::Identity());
  ASSERT_EQ(per_scan.size(), static_cast<std::size_t>(kScans));
  std::size_t total = 0;
  for (int j = 0; j < kScans; ++j) {
    const bool reaches = kScanSpacingM * j >= FirstReachingTravel(options);
    EXPECT_EQ(per_scan[static_cast<std::size_t>(j)], reaches ? 50u : 0u) << "scan " << j;
    total += per_scan[static_cast<std::size_t>(j)];
  }
  EXPECT_EQ(total, swathe.CountProjected(Eigen::Isometry3d::Identity()));
}

TEST(SwatheTrim, KeepsTheScansThatReachTheImagePlusTheMargin) {
  const CalibrationInput input = MakeInput();
  for (const double margin_m : {0.0, 1.0, 2.0}) {
    CalibrationOptions options;
    options.swathe_trim_margin_m = margin_m;
    const PairCost pair = BuildPairCost(input, input.rig.cameras[0], "lidar", options);
    ASSERT_EQ(pair.SceneCount(), 1);
    const double first_m = FirstReachingTravel(options);
    int expected = 0;
    for (int j = 0; j < kScans; ++j) expected += kScanSpacingM * j >= first_m - margin_m - 1e-9 ? 1 : 0;
    EXPECT_EQ(pair.Scenes()[0].ScanCount(), static_cast<std::size_t>(expected)) << "margin " << margin_m;
    EXPECT_LT(expected, kScans);
    // Every point that projected before trimming still does.
    EXPECT_EQ(pair.Scenes()[0].CountProjected(Eigen::Isometry3d::Identity()),
              50u * static_cast<std::size_t>(kScans - static_cast<int>(first_m / kScanSpacingM)));
  }
}

TEST(SwatheTrim, NegativeMarginKeepsEveryScanAndSoDoesASceneThatDoesNotProject) {
  CalibrationInput input = MakeInput();
  CalibrationOptions options;
  options.swathe_trim_margin_m = -1.0;
  EXPECT_EQ(BuildPairCost(input, input.rig.cameras[0], "lidar", options).Scenes()[0].ScanCount(),
            static_cast<std::size_t>(kScans));
  // Lidar turned to face backwards at the initial guess: nothing projects, nothing is trimmed.
  input.rig.lidars[0].T_base_lidar.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  input.rig.lidars[0].T_base_lidar.translation() = Eigen::Vector3d(0.0, 0.0, -20.0);
  options.swathe_trim_margin_m = 1.0;
  const PairCost pair = BuildPairCost(input, input.rig.cameras[0], "lidar", options);
  EXPECT_EQ(pair.Scenes()[0].CountProjected(Eigen::Isometry3d::Identity() * input.rig.lidars[0].T_base_lidar), 0u);
  EXPECT_EQ(pair.Scenes()[0].ScanCount(), static_cast<std::size_t>(kScans));
}

TEST(SwatheTrim, OptionsRejectANonFiniteMargin) {
  CalibrationOptions options;
  options.swathe_trim_margin_m = std::nan("");
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("swathe_trim_margin_m"), std::string::npos);
}

}  // namespace
}  // namespace scenecal
