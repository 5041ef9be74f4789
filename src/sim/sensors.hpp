// Sensor models of the simulator: a camera rendered by ray casting and a
// line-scanning (2D) or spinning (3D) lidar, both looking into a World.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera.hpp"
#include "core/rig.hpp"
#include "sim/world.hpp"

namespace scenecal::sim {

struct RenderSettings {
  bool shadows = true;
  double sun_irradiance = 2.0;     // relative units: a white surface facing the sun
  double sky_irradiance = 0.55;    // diffuse light from the sky
  double exposure = 0.6;           // linear scale before the sensor
  double vignetting = 0.3;         // relative fall-off at the image corners
  double blur_sigma_px = 0.7;      // optical blur (Gaussian), at 1280 px width
  double read_noise = 0.006;       // linear units, 1-sigma
  double shot_noise = 0.0015;      // variance per unit of linear signal
  double gamma = 2.2;
  bool noise = true;               // sensor noise on/off (off for tests of geometry)
};

// Renders the 8-bit grey image the camera sees from T_world_camera (camera
// frame: x right, y down, z forward). noise_key makes the sensor noise a
// function of (key, pixel) only. Rows run in parallel (TBB).
cv::Mat RenderImage(const World& world, const CameraModel& camera, const Eigen::Isometry3d& T_world_camera,
                    const RenderSettings& settings, std::uint64_t noise_key);

// Linear radiance of one ray before the sensor (exposure, vignetting, blur,
// noise and gamma are applied by RenderImage).
double RayRadiance(const World& world, const Ray& ray, const RenderSettings& settings);

struct LidarModel {
  LidarKind kind = LidarKind::k2d;
  std::vector<Eigen::Vector3d> beam_directions;  // unit, lidar frame; 2D: in the x-y plane
  double min_range_m = 0.5;
  double max_range_m = 50.0;
  double range_noise_m = 0.012;     // 1-sigma
  double reflectance_scale = 2000;  // reported value of a unit-reflectivity surface seen head-on, near
  double range_falloff_m = 40.0;    // reflectance halves at this range (infinity: no fall-off)
  double incidence_exponent = 0.8;  // reflectance ~ cos(incidence)^exponent (0: independent of the angle)
  double detection_threshold = 0.025;  // weaker returns (reflectivity x cos x range factor) are lost

  // SICK LMS-151: 541 beams over 270 deg in the x-y plane centred on +x, 50 m.
  static LidarModel PushBroom();
  // 32 beams over +-15 deg elevation, every azimuth_step_deg around +z, 100 m.
  static LidarModel Spinning(double azimuth_step_deg);
};

struct ScanStatistics {
  std::size_t returns = 0;
  std::size_t no_returns = 0;
};

// One scan from T_world_lidar: a record per beam, in beam order; no-returns
// (sky, out of range, too weak) are NaN records as FORMAT.md allows. Noise is
// a function of (noise_key, beam) only.
std::vector<LidarPoint> ScanLidar(const World& world, const LidarModel& lidar, const Eigen::Isometry3d& T_world_lidar,
                                  std::uint64_t noise_key, ScanStatistics* statistics = nullptr);

}  // namespace scenecal::sim
