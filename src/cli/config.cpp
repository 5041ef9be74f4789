#include "cli/config.hpp"

#include <algorithm>

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

// Applies the options of `file` that are not set yet; returns what it set, as typed.
std::vector<std::string> ApplyOptionFile(CLI::App* command, const io::OptionFile& file, bool is_preset) {
  std::vector<std::string> words;
  for (const io::OptionValue& entry : file.options) {
    const std::string where = fmt::format("{}: line {}: {}", file.source, entry.line, entry.name);
    CLI::Option* option = command->get_option_no_throw("--" + entry.name);
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
  }
  return words;
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

void AddConfigOptions(CLI::App* command, ConfigArguments* args) {
  command
      ->add_option("--config", args->files,
                   "Options from a YAML file: option names without their -- as keys (e.g. `thin: 2`), a list for "
                   "several values; or a result file, whose options block repeats its run. May be given several "
                   "times: the command line wins, then the files in order, then --setting")
      ->check(CLI::ExistingFile)
      ->configurable(false);
  command->add_option("--setting", args->setting, SettingHelp())->check(CLI::IsMember(PresetNames()));
}

AppliedConfiguration ApplyConfiguration(CLI::App* command, const ConfigArguments& args) {
  for (const std::string& path : args.files) ApplyOptionFile(command, io::ReadOptionFile(path), false);
  AppliedConfiguration applied;
  if (args.setting.empty()) return applied;  // --setting is read after the files: one may name it
  const io::OptionFile& preset = PresetFile(args.setting);
  applied.setting = args.setting;
  applied.setting_words = ApplyOptionFile(command, preset, true);
  applied.requires_push_broom_drive = preset.requires_data == io::kRequiresPushBroomDrive;
  return applied;
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

std::string PushBroomDriveMisfit(const Rig& rig, std::size_t trajectory_poses) {
  const char* why = !rig.HasPushBroomLidar() ? "no push-broom lidar (rig.yaml: no lidar of kind 2d)"
                    : trajectory_poses < 2     ? "a single-pose trajectory"
                                               : nullptr;
  if (why == nullptr) return "";
  return fmt::format("the data have {}; the preset is for swathes that a moving 2D (push-broom) lidar builds over a "
                     "drive (on single frames its fixed point sets and L-BFGS run away: docs/findings.md, \"Real "
                     "single frames\")",
                     why);
}

}  // namespace scenecal::cli
