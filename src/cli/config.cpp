#include "cli/config.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "cli/presets.hpp"
#include "io/error.hpp"

namespace scenecal::cli {

namespace {

const io::OptionFile& PresetFile(const std::string& name) {
  static const std::vector<io::OptionFile> files = [] {
    std::vector<io::OptionFile> parsed;
    for (const Preset& preset : Presets()) {
      parsed.push_back(io::ParseOptionText(preset.text, "config/" + preset.name + ".yaml"));
    }
    return parsed;
  }();
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (Presets()[i].name == name) return files[i];
  }
  throw io::InputError("--setting: no preset named '" + name + "'");  // the option's check lists the names
}

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const Preset& preset : Presets()) names.push_back(preset.name);
  return names;
}

std::string Typed(const io::OptionValue& option) {
  return fmt::format("--{} {}", option.name, fmt::join(option.values, ","));
}

// --setting's help: each preset's description and options, from config/.
std::string SettingHelp() {
  std::string help = "A preset: a named set of options measured together (config/NAME.yaml, as --config would read "
                     "it); an option given on the command line or in a --config file keeps its own value, and the "
                     "result records what the preset set. ";
  for (const Preset& preset : Presets()) {
    const io::OptionFile& file = PresetFile(preset.name);
    std::vector<std::string> typed;
    for (const io::OptionValue& option : file.options) typed.push_back(Typed(option));
    help += fmt::format("{}, for {}: {}. ", preset.name, file.description, fmt::join(typed, " "));
  }
  return help + "A --refresh-border in percent is of the widest image (48 px at 1280)";
}

// Applies the options of `file` that are not set yet; returns what it set, as
// typed, and adds their names to *set_options when given.
std::vector<std::string> ApplyOptionFile(CLI::App* command, const io::OptionFile& file, bool is_preset,
                                         std::vector<std::string>* set_options = nullptr) {
  std::vector<std::string> words;
  for (const io::OptionValue& entry : file.options) {
    const std::string where = fmt::format("{}: line {}: {}", file.source, entry.line, entry.name);
    CLI::Option* option = command->get_option_no_throw("--" + entry.name);
    // `experiment` runs every scheme of its --schemes, each in one solve: a preset's scheme and its centred
    // final stage (a second solve) are for `calibrate`.
    if (is_preset && option == nullptr && (entry.name == "scheme" || entry.name == "final-swathe") &&
        command->get_option_no_throw("--schemes")) {
      continue;
    }
    if (option == nullptr || !option->get_configurable() || option == command->get_help_ptr()) {
      throw io::InputError(fmt::format("{}: not an option that a file can set for `scenecal {}` (see scenecal {} "
                                       "--help; dataset and output paths go on the command line)",
                                       where, command->get_name(), command->get_name()));
    }
    if (option->count() > 0) continue;  // the command line, or an earlier file, set it
    io::OptionValue applied = entry;
    if (is_preset && entry.name == "motion-correction" && OptionSet(command, "--odometry-scale")) {
      std::erase(applied.values, "drive-scale");  // the drive's scale is given
      if (applied.values.empty()) continue;
    }
    for (const std::string& value : applied.values) option->add_result(value);
    try {
      option->run_callback();  // CLI11's checks, as on the command line
    } catch (const CLI::Error& e) {
      throw io::InputError(fmt::format("{}: {}", where, e.what()));
    }
    words.push_back(Typed(applied));
    if (set_options != nullptr) set_options->push_back("--" + entry.name);
  }
  return words;
}

// Back to the default: its value through the option's own callback, then unset.
void ResetToDefault(CLI::Option* option) {
  const std::string default_text = option->get_default_str();
  if (default_text.empty()) {
    // Every option a preset sets has a default; one without could not be reset.
    throw std::logic_error("preset option " + option->get_name() + " has no default to go back to");
  }
  SetOptionValue(option, default_text);
  option->clear();
}

// An option's default as a list of values (CLI11 writes a list's as "[a,b]").
std::vector<std::string> DefaultValues(const CLI::Option& option) {
  std::string text = option.get_default_str();
  if (text.empty()) return {};
  if (option.get_items_expected_max() <= 1 || text.front() != '[' || text.back() != ']') return {text};
  std::vector<std::string> values;
  text = text.substr(1, text.size() - 2);
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    values.push_back(text.substr(start, comma - start));
    start = comma + 1;
  }
  return values;
}

}  // namespace

void SetOptionValue(CLI::Option* option, const std::string& text) {
  option->clear();
  option->add_result(text);
  option->run_callback();
}

void AddConfigOptions(CLI::App* command, ConfigArguments* args, bool automatic) {
  command
      ->add_option("--config", args->files,
                   "Options from a YAML file: option names without their -- as keys (e.g. `thin: 2`), a list for "
                   "several values; or a result file, whose options block repeats its run. May be given several "
                   "times: the command line wins, then the files in order, then --setting")
      ->check(CLI::ExistingFile)
      ->configurable(false);
  if (!automatic) {
    command->add_option("--setting", args->setting, SettingHelp())->check(CLI::IsMember(PresetNames()));
    return;
  }
  std::vector<std::string> names = PresetNames();
  names.push_back(kAutomaticSetting);
  args->setting = kAutomaticSetting;
  command
      ->add_option("--setting", args->setting,
                   SettingHelp() + ". auto (the default) chooses from the data and says why: a 2D (push-broom) lidar on "
                                   "a drive gets push-broom, or push-broom-drifting when rig.yaml's trajectory_source "
                                   "is visual-odometry; when it is not given, a held-out test decides whether the "
                                   "trajectory drifts within the swathes (then a second solve, from the first's answer); 3D lidars on a "
                                   "drive get 3d-lidar; single frames get none (their own defaults)")
      ->check(CLI::IsMember(names))
      ->capture_default_str();
}

AppliedConfiguration ApplyConfiguration(CLI::App* command, const ConfigArguments& args) {
  for (const std::string& path : args.files) ApplyOptionFile(command, io::ReadOptionFile(path), false);
  AppliedConfiguration applied;
  if (args.setting.empty()) return applied;  // --setting is read after the files: one may name it
  if (args.setting == kAutomaticSetting) {
    applied.automatic = true;  // the data choose (ChooseSetting)
    return applied;
  }
  ApplyPreset(command, args.setting, &applied);
  return applied;
}

void ApplyPreset(CLI::App* command, const std::string& name, AppliedConfiguration* applied) {
  const io::OptionFile& preset = PresetFile(name);
  for (const std::string& option : applied->set_options) ResetToDefault(command->get_option(option));
  applied->set_options.clear();
  applied->setting = name;
  applied->setting_words = ApplyOptionFile(command, preset, true, &applied->set_options);
  applied->requires_data = preset.requires_data;
  if (applied->automatic) SetOptionValue(command->get_option("--setting"), name);
}

std::string PushBroomPresetFor(TrajectorySource source) {
  switch (source) {
    case TrajectorySource::kExact:
    case TrajectorySource::kIns:
    case TrajectorySource::kLidarOdometry:
      return "push-broom";
    case TrajectorySource::kVisualOdometry:
      return "push-broom-drifting";
    case TrajectorySource::kUnknown:
      break;
  }
  return "";
}

AutomaticChoice ChooseSetting(const Rig& rig, std::size_t trajectory_poses, bool single_process) {
  AutomaticChoice choice;
  if (trajectory_poses < 2) {
    choice.reason = "single frame(s): no preset (the single-frame defaults)";
    return choice;
  }
  if (!rig.HasPushBroomLidar()) {
    choice.preset = "3d-lidar";
    choice.reason = "3D lidar(s) on a drive";
    return choice;
  }
  const std::string source = TrajectorySourceName(rig.trajectory_source);
  choice.preset = PushBroomPresetFor(rig.trajectory_source);
  if (!choice.preset.empty()) {
    choice.reason = "a 2D (push-broom) lidar on a drive; rig.yaml: trajectory_source " + source;
    return choice;
  }
  if (!single_process) {
    choice.preset = "push-broom-drifting";
    choice.reason = "a 2D (push-broom) lidar on a drive, trajectory_source not given and no held-out drift test "
                    "across MPI ranks: the drifting preset, whose cost on good odometry is the smaller mistake";
    return choice;
  }
  choice.preset = "push-broom";
  choice.test_drift = true;
  choice.reason = "a 2D (push-broom) lidar on a drive, trajectory_source not given: the held-out drift test decides";
  return choice;
}

std::vector<io::OptionValue> RunOptions(const CLI::App* command) {
  std::vector<io::OptionValue> options;
  for (const CLI::Option* option : command->get_options()) {
    if (option->get_lnames().empty() || !option->get_configurable() || option == command->get_help_ptr()) continue;
    std::vector<std::string> values = option->count() > 0 ? option->results() : DefaultValues(*option);
    if (!values.empty()) options.push_back({option->get_lnames().front(), std::move(values)});
  }
  return options;
}

bool OptionSet(const CLI::App* command, const std::string& name) {
  const CLI::Option* option = command == nullptr ? nullptr : command->get_option_no_throw(name);
  return option != nullptr && option->count() > 0;
}

std::string DataMisfit(const std::string& requires_data, const Rig& rig, std::size_t trajectory_poses) {
  const bool push_broom = requires_data == io::kRequiresPushBroomDrive;
  if (!push_broom && requires_data != io::kRequiresDrive) return "";
  const char* why = push_broom && !rig.HasPushBroomLidar() ? "no push-broom lidar (rig.yaml: no lidar of kind 2d)"
                    : trajectory_poses < 2                  ? "a single-pose trajectory"
                                                            : nullptr;
  if (why == nullptr) return "";
  return fmt::format("the data have {}; the preset is for swathes that a moving {}lidar builds over a drive (on "
                     "single frames its fixed point sets and L-BFGS run away: docs/findings.md, \"Real single "
                     "frames\")",
                     why, push_broom ? "2D (push-broom) " : "");
}

}  // namespace scenecal::cli
