// The lidar odometry as a plugin the scenecal command loads when it needs it.
//
// Open3D pulls in ~50 shared libraries of its own (its renderer, GL, ...):
// linked into the command (215 libraries instead of 168), every invocation
// and every test process loaded them for a feature few of them use. The command instead dlopen()s
// libscenecal_odometry.so from its own folder for `odometry` and for KITTI
// snippets without poses (LoadOdometryPlugin in cli/odometry_plugin.hpp).
#pragma once

#include <functional>
#include <vector>

#include "odometry/lidar_odometry.hpp"

namespace scenecal::odometry {

// Runs the odometry over the scans next_scan gives (it fills *scan and returns
// true, or returns false at the end; an exception it throws passes through).
using RunLidarOdometryFn = std::vector<OdometryStep> (*)(const LidarOdometryOptions& options,
                                                         const std::function<bool(LidarScan* scan)>& next_scan);

// The plugin's one exported symbol: returns its RunLidarOdometry.
inline constexpr char kPluginEntryPoint[] = "scenecal_lidar_odometry_entry";
inline constexpr char kPluginFileName[] = "libscenecal_odometry.so";
using PluginEntryFn = RunLidarOdometryFn (*)();

}  // namespace scenecal::odometry
