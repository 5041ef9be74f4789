// Lidar odometry for 3D lidars: the lidar's motion from its own scans, for
// recordings that come without poses. Each scan is registered to a local map
// of the last keyframes (point-to-plane ICP with a robust Tukey kernel, from
// Open3D), not to the previous scan alone: traffic moving beside the car fools
// a registration over 0.1 s, while a map of several frames spread over metres
// keeps the static street, and the kernel down-weights what does not fit it.
//
// Incremental: the caller feeds scans in time order (it reads them; this
// library reads no files and prints nothing).
#pragma once

#include <cstddef>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/rig.hpp"
#include "core/trajectory.hpp"

namespace open3d::geometry {
class PointCloud;
}

namespace scenecal::odometry {

struct LidarOdometryOptions {
  double voxel_m = 0.5;              // scan and map down-sampling
  double min_range_m = 2.5;          // returns nearer than this (the vehicle itself) are dropped
  double max_range_m = 80.0;         // and beyond this (sparse, noisy)
  double max_correspondence_m = 1.5; // ICP: pairs further apart are no pair (fine pass: a third of it)
  int max_iterations = 30;           // per ICP pass
  int map_keyframes = 12;            // scans kept in the local map
  double keyframe_distance_m = 1.0;  // a scan becomes a keyframe after this much travel
  double keyframe_rotation_deg = 5.0;  // ... or this much turn
  double min_fitness = 0.3;          // fraction of scan points with a map partner below which a registration is weak

  bool IsValid(std::string* why = nullptr) const;
};

struct OdometryStep {
  TimeUs t_us = 0;
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();  // world = the first scan's lidar frame
  double fitness = 1.0;     // fraction of the scan's points registered to the map (the first scan: 1)
  double rmse_m = 0.0;      // of the registered pairs
  std::size_t points = 0;   // after range filter and down-sampling
  bool weak = false;        // fitness below min_fitness, or too few points: the pose follows the prediction
};

class LidarOdometry {
 public:
  explicit LidarOdometry(LidarOdometryOptions options);
  ~LidarOdometry();
  LidarOdometry(const LidarOdometry&) = delete;
  LidarOdometry& operator=(const LidarOdometry&) = delete;

  // Registers the next scan (times strictly increasing; std::invalid_argument
  // otherwise) and returns its pose.
  const OdometryStep& Add(const LidarScan& scan);
  const std::vector<OdometryStep>& steps() const { return steps_; }

 private:
  Eigen::Isometry3d Predict(TimeUs t_us) const;
  void AddKeyframe(const open3d::geometry::PointCloud& scan_in_lidar, const Eigen::Isometry3d& T_world_lidar);

  LidarOdometryOptions options_;
  std::vector<OdometryStep> steps_;
  std::deque<std::shared_ptr<open3d::geometry::PointCloud>> keyframes_;  // world frame
  std::shared_ptr<open3d::geometry::PointCloud> map_;                    // keyframes merged, with normals
  Eigen::Isometry3d T_world_last_keyframe_ = Eigen::Isometry3d::Identity();
};

// How far an odometry's base trajectory drifts from a reference (a recorded
// or simulated trajectory), over the times both cover, both taken relative to
// their first common pose.
struct DriftStatistics {
  std::size_t compared = 0;       // poses with a reference pose
  double distance_m = 0.0;        // travelled between the first and last compared pose (reference)
  double end_translation_m = 0.0; // error of the last pose relative to the first
  double end_rotation_deg = 0.0;
  // Mean relative error over every segment of segment_m travelled: translation
  // in percent of the length, rotation in degrees per metre (0 when the drive
  // is shorter than one segment).
  std::size_t segments = 0;
  double segment_translation_percent = 0.0;
  double segment_rotation_deg_per_m = 0.0;
};

DriftStatistics CompareWithReference(const std::vector<TimeUs>& times_us,
                                     const std::vector<Eigen::Isometry3d>& T_world_base, const Trajectory& reference,
                                     double segment_m);

}  // namespace scenecal::odometry
