// Test support: small random swathes for the kernel tests (fast kernels
// against their straightforward references). A 320x240 camera of any model,
// scans of random points in a frustum in front of it (some behind, beside or
// too near) and scans at several poses, with point counts that are not
// multiples of the kernel's block.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "core/geometry.hpp"
#include "core/swathe.hpp"

namespace scenecal::test {

inline CameraModel MakeKernelTestCamera(CameraModelKind kind, double fx = 260.0, double fy = 260.0) {
  CameraModel camera;
  camera.width = 320;
  camera.height = 240;
  camera.kind = kind;
  camera.fx = fx;
  camera.fy = fy;
  camera.cx = 161.3;
  camera.cy = 118.7;
  if (kind == CameraModelKind::kRadTan) camera.distortion = {-0.21, 0.05, 0.001, -0.0007, -0.004};
  if (kind == CameraModelKind::kEquidistant) camera.distortion = {0.02, -0.01, 0.003, -0.0005};
  return camera;
}

// Points in the lidar frame (= camera frame at the identity extrinsic): depth
// uniform in [-2, 25] m, |x| <= spread_x * depth, |y| <= spread_y * depth;
// reflectance uniform in [0, 255].
inline LidarScan RandomFrustumScan(std::mt19937& rng, int points, float spread_x = 0.75f, float spread_y = 0.6f) {
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), depth(-2.0f, 25.0f), reflectance(0.0f, 255.0f);
  LidarScan scan;
  for (int i = 0; i < points; ++i) {
    const float z = depth(rng);
    scan.points.push_back({spread_x * z * unit(rng), spread_y * z * unit(rng), z, reflectance(rng)});
  }
  return scan;
}

struct RandomSwatheSpec {
  int scans = 5;
  int first_scan_points = 700;  // scan j has first_scan_points + j * scan_points_step points
  int scan_points_step = 97;
  float spread_x = 0.75f, spread_y = 0.6f;  // see RandomFrustumScan
};

struct TestSwathe {
  CameraInfo camera;
  std::vector<LidarScan> scans;
  SceneSwathe swathe;
};

// Scan j's pose from the frame's in MakeRandomSwathe: the tuple j * (5 cm,
// -2 cm, 30 cm, 0.4, -0.3, 0.2 deg).
inline Eigen::Isometry3d RandomSwatheScanPose(int j) {
  Vector6d tuple;
  tuple << 0.05 * j, -0.02 * j, 0.3 * j, RadiansFromDegrees(0.4 * j), RadiansFromDegrees(-0.3 * j),
      RadiansFromDegrees(0.2 * j);
  return TransformFromTuple(tuple);
}

// A swathe of spec.scans random scans seen by `camera` in `image` (CV_32F,
// camera-sized); scan j at RandomSwatheScanPose(j) from the frame.
inline TestSwathe MakeRandomSwathe(const CameraModel& camera, const cv::Mat& image, std::uint32_t seed,
                                   const RandomSwatheSpec& spec = {}) {
  TestSwathe t;
  t.camera.name = "cam";
  t.camera.model = camera;
  std::mt19937 rng(seed);
  Scene scene;
  scene.camera = "cam";
  scene.lidar = "lidar";
  for (int j = 0; j < spec.scans; ++j)
    t.scans.push_back(RandomFrustumScan(rng, spec.first_scan_points + spec.scan_points_step * j, spec.spread_x,
                                        spec.spread_y));
  std::vector<const LidarScan*> scan_pointers;
  for (int j = 0; j < spec.scans; ++j) {
    scene.scans.push_back({j, RandomSwatheScanPose(j)});
    scan_pointers.push_back(&t.scans[static_cast<std::size_t>(j)]);
  }
  t.swathe = SceneSwathe::Build(scene, t.camera, image, scan_pointers, SwatheOptions{}, NormalisationOptions{});
  return t;
}

}  // namespace scenecal::test
