#include "odometry/plugin.hpp"

namespace scenecal::odometry {
namespace {

std::vector<OdometryStep> RunLidarOdometry(const LidarOdometryOptions& options,
                                           const std::function<bool(LidarScan* scan)>& next_scan) {
  LidarOdometry estimator(options);
  LidarScan scan;
  while (next_scan(&scan)) estimator.Add(scan);
  return estimator.steps();
}

}  // namespace
}  // namespace scenecal::odometry

extern "C" __attribute__((visibility("default"))) scenecal::odometry::RunLidarOdometryFn
scenecal_lidar_odometry_entry() {
  return &scenecal::odometry::RunLidarOdometry;
}
