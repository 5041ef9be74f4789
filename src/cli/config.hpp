// Options from files: `--config FILE` (any option set, or a result file,
// whose `options` block repeats its run) and `--setting NAME` (a preset,
// config/NAME.yaml, compiled in). An option given on the command line keeps
// its own value; then each --config file in the order given; then the preset.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/rig.hpp"
#include "io/option_file.hpp"

namespace scenecal::cli {

// --setting's value that leaves the choice of the preset to the data (ChooseSetting).
inline constexpr const char* kAutomaticSetting = "auto";

struct ConfigArguments {
  std::vector<std::string> files;  // --config, in the order given
  std::string setting;             // --setting: a preset's name, or kAutomaticSetting
};

// Registers --config and --setting on `command`; with `automatic`, --setting
// accepts kAutomaticSetting and defaults to it (calibrate), else it has no default.
void AddConfigOptions(CLI::App* command, ConfigArguments* args, bool automatic = false);

// What the preset set, for the log and the result's settings.
struct AppliedConfiguration {
  std::string setting;                     // the preset's name; empty without one
  std::vector<std::string> setting_words;  // e.g. "--thin 2": what it set, as typed
  std::vector<std::string> set_options;    // the options it set, e.g. "--thin"
  std::string requires_data;               // its `requires` (io::kRequiresPushBroomDrive, kRequiresDrive), empty: any
  bool automatic = false;                  // --setting auto: the preset is chosen from the data (ChooseSetting)
  std::string automatic_reason;            // why ChooseSetting chose it

  // Whether the preset set `option` (e.g. "--stages"): not given on the command line or in a --config file.
  bool PresetSet(const std::string& option) const {
    return std::find(set_options.begin(), set_options.end(), option) != set_options.end();
  }
};

// The push-broom preset measured for a trajectory from `source`: push-broom
// for exact, INS or lidar odometry, push-broom-drifting for visual odometry;
// empty when the source is unknown.
std::string PushBroomPresetFor(TrajectorySource source);

// --setting auto: the preset for this rig and trajectory, and why. A 2D
// (push-broom) lidar on a drive gets a push-broom preset by rig.yaml's
// trajectory_source; when the source is unknown, `push-broom` first and the
// held-out drift test (TestDriftAt) then decides on `push-broom-drifting`
// (without one process to test in, push-broom-drifting: the cheaper mistake).
// 3D lidars on a drive get `3d-lidar`; single frames no preset (their own
// defaults).
struct AutomaticChoice {
  std::string preset;        // empty: none
  std::string reason;
  bool test_drift = false;   // push-broom now; the held-out drift test decides on push-broom-drifting
};
AutomaticChoice ChooseSetting(const Rig& rig, std::size_t trajectory_poses, bool single_process);

// Applies the preset `name` to the options of `command` not set yet (as
// ApplyConfiguration does) in place of the one `applied` describes, whose
// options go back to their defaults first; *applied then describes `name`,
// and --setting reads `name` (for the result's options block).
void ApplyPreset(CLI::App* command, const std::string& name, AppliedConfiguration* applied);

// The option's value replaced by `text`, through the option's own callback
// (set, as by the command line).
void SetOptionValue(CLI::Option* option, const std::string& text);

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

// Why a preset that requires `requires_data` (its `requires` key) does not
// fit a dataset with this rig and this many trajectory poses: a push-broom
// drive needs a 2D lidar and a drive, a drive more than one pose (on single
// frames the presets' fixed point sets and L-BFGS run away); empty when it
// fits or nothing is required.
std::string DataMisfit(const std::string& requires_data, const Rig& rig, std::size_t trajectory_poses);

}  // namespace scenecal::cli
