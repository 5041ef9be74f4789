// What a calibration produces (FORMAT.md "Calibration result"), independent of files.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/geometry.hpp"

namespace scenecal {

struct LidarCalibration {
  std::string lidar;
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();
  std::optional<Vector6d> sigma;  // 1-sigma (m, m, m, rad, rad, rad), where estimated
  // Covariance of the error of [x y z roll pitch yaw] (m, rad; symmetric), where estimated.
  std::optional<Matrix6d> covariance;
};

struct PairCalibration {
  std::string camera;
  std::string lidar;
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();
  double cost = 0.0;  // final value of the metric for this pair
};

struct CalibrationResult {
  std::vector<LidarCalibration> lidars;
  std::vector<PairCalibration> pairs;
  std::string termination;                    // why the solver stopped, one line
  std::map<std::string, std::string> settings;  // options as used, for the record
  std::map<std::string, double> timings_s;      // wall-clock seconds per stage
  std::vector<std::string> warnings;
};

}  // namespace scenecal
