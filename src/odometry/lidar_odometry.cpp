#include "odometry/lidar_odometry.hpp"

#include <cmath>
#include <stdexcept>

#include <open3d/geometry/KDTreeSearchParam.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/RobustKernel.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>

#include "core/geometry.hpp"

namespace scenecal::odometry {

namespace registration = open3d::pipelines::registration;
using open3d::geometry::PointCloud;

namespace {

// A scan registers reliably only with enough structure left after thinning.
constexpr std::size_t kMinPoints = 50;

// The scan's returns within the range band, down-sampled on the voxel grid.
std::shared_ptr<PointCloud> Preprocess(const LidarScan& scan, const LidarOdometryOptions& options) {
  PointCloud cloud;
  cloud.points_.reserve(scan.points.size());
  const double min2 = options.min_range_m * options.min_range_m;
  const double max2 = options.max_range_m * options.max_range_m;
  for (const LidarPoint& p : scan.points) {
    const Eigen::Vector3d point(p.x, p.y, p.z);
    const double range2 = point.squaredNorm();
    if (range2 >= min2 && range2 <= max2) cloud.points_.push_back(point);
  }
  return cloud.VoxelDownSample(options.voxel_m);
}

// The relative motion `delta` over one interval stretched to `ratio` intervals
// (constant velocity on SE(3), by the axis-angle of the rotation).
Eigen::Isometry3d ScaleMotion(const Eigen::Isometry3d& delta, double ratio) {
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  const Eigen::AngleAxisd turn(delta.linear());
  scaled.linear() = Eigen::AngleAxisd(turn.angle() * ratio, turn.axis()).toRotationMatrix();
  scaled.translation() = delta.translation() * ratio;
  return scaled;
}

}  // namespace

LidarOdometry::LidarOdometry(LidarOdometryOptions options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument("lidar odometry: " + why);
}

LidarOdometry::~LidarOdometry() = default;

Eigen::Isometry3d LidarOdometry::Predict(TimeUs t_us) const {
  const OdometryStep& last = steps_.back();
  if (steps_.size() < 2) return last.T_world_lidar;
  const OdometryStep& before = steps_[steps_.size() - 2];
  const Eigen::Isometry3d delta = before.T_world_lidar.inverse() * last.T_world_lidar;
  const double ratio = static_cast<double>(t_us - last.t_us) / static_cast<double>(last.t_us - before.t_us);
  return last.T_world_lidar * ScaleMotion(delta, ratio);
}

void LidarOdometry::AddKeyframe(const PointCloud& scan_in_lidar, const Eigen::Isometry3d& T_world_lidar) {
  auto keyframe = std::make_shared<PointCloud>(scan_in_lidar);
  keyframe->Transform(T_world_lidar.matrix());
  keyframes_.push_back(keyframe);
  while (keyframes_.size() > static_cast<std::size_t>(options_.map_keyframes)) keyframes_.pop_front();
  PointCloud merged;
  for (const auto& frame : keyframes_) merged += *frame;
  map_ = merged.VoxelDownSample(options_.voxel_m);
  map_->EstimateNormals(open3d::geometry::KDTreeSearchParamHybrid(3.0 * options_.voxel_m, 20));
  T_world_last_keyframe_ = T_world_lidar;
}

const OdometryStep& LidarOdometry::Add(const LidarScan& scan) {
  if (!steps_.empty() && scan.t_us <= steps_.back().t_us) {
    throw std::invalid_argument("lidar odometry: scan times must increase (" + std::to_string(scan.t_us) +
                                " after " + std::to_string(steps_.back().t_us) + ")");
  }
  const std::shared_ptr<PointCloud> cloud = Preprocess(scan, options_);
  OdometryStep step;
  step.t_us = scan.t_us;
  step.points = cloud->points_.size();
  if (steps_.empty()) {
    step.weak = step.points < kMinPoints;
    steps_.push_back(step);
    if (!step.weak) AddKeyframe(*cloud, step.T_world_lidar);
    return steps_.back();
  }
  const Eigen::Isometry3d predicted = Predict(scan.t_us);
  step.T_world_lidar = predicted;
  if (map_ == nullptr || step.points < kMinPoints) {
    step.weak = true;
    if (map_ == nullptr && step.points >= kMinPoints) AddKeyframe(*cloud, step.T_world_lidar);
    steps_.push_back(step);
    return steps_.back();
  }
  // Coarse then fine: the wide pass catches a prediction that is off (a
  // braking car), the narrow one settles on the static structure.
  const registration::ICPConvergenceCriteria criteria(1e-6, 1e-6, options_.max_iterations);
  Eigen::Matrix4d estimate = predicted.matrix();
  registration::RegistrationResult result;
  for (const double distance : {options_.max_correspondence_m, options_.max_correspondence_m / 3.0}) {
    const auto kernel = std::make_shared<registration::TukeyLoss>(distance / 2.0);
    result = registration::RegistrationICP(*cloud, *map_, distance, estimate,
                                           registration::TransformationEstimationPointToPlane(kernel), criteria);
    estimate = result.transformation_;
  }
  step.fitness = result.fitness_;
  step.rmse_m = result.inlier_rmse_;
  step.weak = result.fitness_ < options_.min_fitness;
  if (!step.weak) {
    step.T_world_lidar.matrix() = estimate;
    step.T_world_lidar.linear() = NearestRotation(step.T_world_lidar.linear());
  }
  const Eigen::Isometry3d since_keyframe = T_world_last_keyframe_.inverse() * step.T_world_lidar;
  const double turned_deg = DegreesFromRadians(Eigen::AngleAxisd(since_keyframe.linear()).angle());
  if (!step.weak && (since_keyframe.translation().norm() >= options_.keyframe_distance_m ||
                     turned_deg >= options_.keyframe_rotation_deg)) {
    AddKeyframe(*cloud, step.T_world_lidar);
  }
  steps_.push_back(step);
  return steps_.back();
}

}  // namespace scenecal::odometry
