// --setting of `calibrate` and `experiment`: named bundles of options that
// were measured together on the simulated push-broom drives (README "What to
// expect", BENCHMARK.md, "Accuracy on the simulated presets"), so that a user types one
// word instead of nine and scales nothing by hand. Each command applies the
// options its command line did not give.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/rig.hpp"

namespace scenecal::cli {

// Whether `name` was given on `command`'s command line (false for a null command).
bool GivenOnCommandLine(const CLI::App* command, const std::string& name);

// The setting names, for the option's check: push-broom (good odometry),
// push-broom-drifting (visual odometry, ~0.01 deg/m).
const std::vector<std::string>& SettingNames();

// One option of a setting as it would be typed; number is its value when numeric.
struct SettingOption {
  std::string name;  // e.g. "--swathe-length"
  std::string value;
  double number = 0.0;
};

// The options `setting` stands for, in the order they are applied; with_alt
// adds the alternation counts (the command runs the alt scheme); with
// odometry_scale_given (--odometry-scale) the drifting setting does not
// estimate the drive's scale again. The border follows the images:
// SettingRefreshBorderPx.
std::vector<SettingOption> SettingOptions(const std::string& setting, bool with_alt,
                                          bool odometry_scale_given = false);

// The setting's --refresh-border for this rig: 3.75 % of its widest image
// (48 px at 1280).
double SettingRefreshBorderPx(const Rig& rig);

// Why `setting` does not fit a dataset with this rig and this many trajectory
// poses (no 2D lidar; a single pose: on single frames its fixed point sets and
// L-BFGS run away); empty when it fits.
std::string SettingMisfit(const Rig& rig, std::size_t trajectory_poses);

// The --setting help text both commands show.
std::string SettingHelp();

}  // namespace scenecal::cli
