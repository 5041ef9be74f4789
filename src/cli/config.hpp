// Options from files: `--config FILE` (any option set, or a result file,
// whose `options` block repeats its run) and `--setting NAME` (a preset,
// config/NAME.yaml, compiled in). An option given on the command line keeps
// its own value; then each --config file in the order given; then the preset.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/rig.hpp"
#include "io/option_file.hpp"

namespace scenecal::cli {

struct ConfigArguments {
  std::vector<std::string> files;  // --config, in the order given
  std::string setting;             // --setting: a preset's name
};

// Registers --config and --setting on `command`.
void AddConfigOptions(CLI::App* command, ConfigArguments* args);

// What the preset set, for the log and the result's settings.
struct AppliedConfiguration {
  std::string setting;                     // the preset's name; empty without one
  std::vector<std::string> setting_words;  // e.g. "--thin 2": what it set, as typed
  bool requires_push_broom_drive = false;  // its `requires: push-broom-drive`
};

// Sets the options of `command` that are not set yet: from each --config
// file, then from the --setting preset (which a file may name). A preset's
// motion-correction leaves out drive-scale when --odometry-scale is set: the
// drive's scale is then known. Throws io::InputError naming the file, the
// option and its line (unknown option, value the option refuses).
AppliedConfiguration ApplyConfiguration(CLI::App* command, const ConfigArguments& args);

// Every option of `command` as this run used it (given, else its default;
// options unset without a default are left out), for the result's `options`
// block: `--config RESULT` then repeats the run.
std::vector<io::OptionValue> RunOptions(const CLI::App* command);

// Whether the option `name` (e.g. "--thin") of `command` is set, on the
// command line or by a configuration (false for a null command).
bool OptionSet(const CLI::App* command, const std::string& name);

// Why a preset that requires a push-broom drive does not fit a dataset with
// this rig and this many trajectory poses (no 2D lidar; a single pose: on
// single frames its fixed point sets and L-BFGS run away); empty when it fits.
std::string PushBroomDriveMisfit(const Rig& rig, std::size_t trajectory_poses);

}  // namespace scenecal::cli
