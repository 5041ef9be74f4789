#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "core/geometry.hpp"
#include "core/validation.hpp"
#include "odometry/lidar_odometry.hpp"

// What the odometry's users need without loading Open3D: its options' check
// and the drift measure.
namespace scenecal::odometry {

bool LidarOdometryOptions::IsValid(std::string* why) const {
  if (!(voxel_m > 0.0) || !std::isfinite(voxel_m)) return Invalid(why, "voxel_m must be a positive number of metres");
  if (!(min_range_m >= 0.0) || !(max_range_m > min_range_m) || !std::isfinite(max_range_m))
    return Invalid(why, "the range band must satisfy 0 <= min_range_m < max_range_m");
  if (!(max_correspondence_m > 0.0) || !std::isfinite(max_correspondence_m))
    return Invalid(why, "max_correspondence_m must be positive");
  if (max_iterations < 1) return Invalid(why, "max_iterations must be at least 1");
  if (map_keyframes < 1) return Invalid(why, "map_keyframes must be at least 1");
  if (!(keyframe_distance_m > 0.0) || !(keyframe_rotation_deg > 0.0))
    return Invalid(why, "keyframe_distance_m and keyframe_rotation_deg must be positive");
  if (!(min_fitness >= 0.0 && min_fitness <= 1.0)) return Invalid(why, "min_fitness must lie in [0, 1]");
  return true;
}

DriftStatistics CompareWithReference(const std::vector<TimeUs>& times_us,
                                     const std::vector<Eigen::Isometry3d>& T_world_base, const Trajectory& reference,
                                     double segment_m) {
  DriftStatistics drift;
  // The poses both trajectories have, each expressed from its first one.
  std::vector<Eigen::Isometry3d> estimated, truth;
  std::vector<double> distance_m;
  for (std::size_t i = 0; i < times_us.size(); ++i) {
    const std::optional<Eigen::Isometry3d> pose = reference.PoseAt(times_us[i]);
    if (!pose) continue;
    estimated.push_back(T_world_base[i]);
    truth.push_back(*pose);
    distance_m.push_back(reference.DistanceAt(times_us[i]));
  }
  drift.compared = estimated.size();
  if (estimated.size() < 2) return drift;
  drift.distance_m = distance_m.back() - distance_m.front();
  const auto error = [](const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& reference_pose) {
    const Eigen::Isometry3d difference = reference_pose.inverse() * estimate;
    return std::make_pair(difference.translation().norm(),
                          DegreesFromRadians(Eigen::AngleAxisd(difference.linear()).angle()));
  };
  const auto [end_m, end_deg] = error(estimated.front().inverse() * estimated.back(), truth.front().inverse() * truth.back());
  drift.end_translation_m = end_m;
  drift.end_rotation_deg = end_deg;
  // Relative errors over every segment of segment_m travelled (KITTI's
  // measure), each start a pose, the end the first pose past the length.
  double translation_sum = 0.0, rotation_sum = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    j = std::max(j, i);
    while (j < estimated.size() && distance_m[j] - distance_m[i] < segment_m) ++j;
    if (j == estimated.size()) break;
    const double length = distance_m[j] - distance_m[i];
    const auto [t_err, r_err] = error(estimated[i].inverse() * estimated[j], truth[i].inverse() * truth[j]);
    translation_sum += t_err / length;
    rotation_sum += r_err / length;
    ++drift.segments;
  }
  if (drift.segments > 0) {
    drift.segment_translation_percent = 100.0 * translation_sum / static_cast<double>(drift.segments);
    drift.segment_rotation_deg_per_m = rotation_sum / static_cast<double>(drift.segments);
  }
  return drift;
}

}  // namespace scenecal::odometry
