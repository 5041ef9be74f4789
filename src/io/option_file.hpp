// Option files: a YAML mapping from a command's option names (without the
// leading --) to their values, as `--config FILE` reads them and as the
// presets in config/ are written. A result file is one too: its `options`
// block records every option of the run, so `--config RESULT` repeats it.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace scenecal::io {

// One option and its values as typed (a list gives several).
struct OptionValue {
  std::string name;  // e.g. "swathe-length"
  std::vector<std::string> values;
  int line = 0;  // 1-based line in the file, for messages
};

struct OptionFile {
  std::string source;       // the file's path, or what stands for it ("preset push-broom")
  std::string description;  // the optional `description` key (presets)
  std::string requires_data;  // the optional `requires` key: kRequiresPushBroomDrive, kRequiresDrive or empty
  std::vector<OptionValue> options;  // in the file's order
};

// A preset's `requires` value: a moving 2D (push-broom) lidar over a drive.
inline constexpr char kRequiresPushBroomDrive[] = "push-broom-drive";
// A preset's `requires` value: a drive (a trajectory of more than one pose), any lidar.
inline constexpr char kRequiresDrive[] = "drive";

// Reads an option file, or a result file's `options` block. Throws InputError
// naming the file, the key and its line: not a mapping, a key given twice, a
// value that is a mapping or empty, a result file without an options block.
OptionFile ReadOptionFile(const std::filesystem::path& path);
// The same for text in memory; `source` stands for the file in messages.
OptionFile ParseOptionText(const std::string& text, const std::string& source);

// The mapping an option file holds (one value as a scalar, several as a list).
YAML::Node OptionsYaml(const std::vector<OptionValue>& options);

}  // namespace scenecal::io
