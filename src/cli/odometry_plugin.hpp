// Loads the lidar odometry plugin (odometry/plugin.hpp) from the scenecal
// executable's folder, once, on first use.
#pragma once

#include "odometry/plugin.hpp"

namespace scenecal::cli {

// The plugin's RunLidarOdometry; std::runtime_error naming the file and
// dlopen's reason when it cannot be loaded.
odometry::RunLidarOdometryFn LoadOdometryPlugin();

}  // namespace scenecal::cli
