// In-memory description of a sensor rig and its data, independent of files.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera.hpp"
#include "core/geometry.hpp"
#include "core/trajectory.hpp"

namespace scenecal {

struct CameraInfo {
  std::string name;
  CameraModel model;
  Eigen::Isometry3d T_base_camera = Eigen::Isometry3d::Identity();  // known (factory) transform
  // 1-sigma of the known transform (m, m, m, rad, rad, rad) in the 6-tuple
  // parameterisation; absent means "no stated uncertainty".
  std::optional<Vector6d> T_base_camera_sigma;

  Eigen::Isometry3d T_camera_base() const { return T_base_camera.inverse(); }
};

enum class LidarKind { k2d, k3d };

struct LidarInfo {
  std::string name;
  LidarKind kind = LidarKind::k2d;
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();  // initial guess
};

// Where the trajectory comes from (rig.yaml's optional trajectory_source):
// how far it can be trusted over a swathe.
enum class TrajectorySource { kUnknown, kExact, kIns, kLidarOdometry, kVisualOdometry };

// "unknown", "exact", "ins", "lidar-odometry", "visual-odometry".
const char* TrajectorySourceName(TrajectorySource source);
bool ParseTrajectorySource(const std::string& name, TrajectorySource* source);
// The accepted names, "exact | ins | ...", for messages.
std::string TrajectorySourceChoices();

struct Rig {
  std::string base_frame;  // names a camera; trajectory poses are of this frame
  std::vector<CameraInfo> cameras;
  std::vector<LidarInfo> lidars;
  TrajectorySource trajectory_source = TrajectorySource::kUnknown;

  const CameraInfo* FindCamera(const std::string& name) const;
  const LidarInfo* FindLidar(const std::string& name) const;
  bool HasPushBroomLidar() const;  // a lidar of kind 2d
};

struct GroundTruth {
  std::map<std::string, Eigen::Isometry3d> T_base_lidar;   // by lidar name
  std::map<std::string, Eigen::Isometry3d> T_base_camera;  // by camera name, where perturbed in rig.yaml
};

// One lidar return in the lidar frame: metres, reflectance as the sensor
// reports it (any non-negative scale).
struct LidarPoint {
  float x, y, z, reflectance;
};
static_assert(sizeof(LidarPoint) == 16, "LidarPoint matches the .bin record layout");

struct LidarScan {
  TimeUs t_us = 0;
  std::vector<LidarPoint> points;  // finite points only
  std::size_t no_returns = 0;       // records skipped for a non-finite value
};

// A grey image: CV_32F intensities in [0, 1].
struct GreyImage {
  TimeUs t_us = 0;
  cv::Mat intensity;
};

}  // namespace scenecal
