#include "io/option_file.hpp"

#include <algorithm>
#include <set>

#include <fmt/format.h>

#include "io/result_file.hpp"
#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace {

constexpr std::size_t kMaxOptionFileBytes = std::size_t{64} << 20;  // as a result file (its history can be long)

// Option names and values are printable UTF-8 text: a control character or
// a broken code point (which a YAML escape can carry) would not survive being
// written back.
void CheckPrintable(const detail::YamlReader& yaml, const YAML::Node& node, const std::string& field) {
  // An escape ("\\uD800") can make what is not UTF-8.
  if (detail::FirstInvalidUtf8(node.Scalar()) != std::string_view::npos) {
    yaml.Fail(node, field, "text that is not UTF-8 (from an escape)", "printable text");
  }
  const std::string& text = node.Scalar();
  if (const auto control = std::find_if(text.begin(), text.end(), detail::IsControlCharacter); control != text.end()) {
    yaml.Fail(node, field, fmt::format("a control character (0x{:02X})", static_cast<unsigned char>(*control)),
              "printable text");
  }
}

// The text with its control characters shown as '?', for messages.
std::string Shown(std::string text) {
  std::replace_if(text.begin(), text.end(), detail::IsControlCharacter, '?');
  return text;
}

OptionFile ParseOptions(const detail::YamlReader& yaml) {
  OptionFile file;
  file.source = yaml.file();
  const YAML::Node& root = yaml.root();
  // A result file: its options block.
  const bool is_result = root.IsMap() && root["format"].IsDefined() && root["format"].IsScalar() &&
                         root["format"].Scalar() == kCalibrationResultFormat;
  const YAML::Node options = is_result ? root["options"] : root;  // yaml-cpp: never reassign a node
  const std::string field = is_result ? "options" : "";
  if (is_result && !options.IsDefined()) {
    yaml.Fail(root, "options", "a result file without an options block",
              "a result written by `scenecal calibrate`, or a mapping of option names to values");
  }
  const auto where = [&](const std::string& key) { return field.empty() ? key : field + "." + key; };
  // Before the duplicate check, whose message shows the key as it is.
  yaml.RequireMap(options, field);
  for (const auto& entry : options) {
    if (entry.first.IsScalar()) CheckPrintable(yaml, entry.first, where(Shown(entry.first.Scalar())));
  }
  yaml.CheckUniqueKeys(options, field);
  for (const auto& entry : options) {
    const std::string key = entry.first.Scalar();
    const YAML::Node& value = entry.second;
    if (key.empty() || key.front() == '-') {
      yaml.Fail(entry.first, where(key), "a key '" + key + "'", "an option name without its leading -- (e.g. thin)");
    }
    if (key == "description" || key == "requires") {
      std::string text = yaml.String(value, where(key));
      if (key == "requires" && text != kRequiresPushBroomDrive && text != kRequiresDrive) {
        yaml.Fail(value, where(key), "'" + text + "'",
                  std::string("'") + kRequiresPushBroomDrive + "' or '" + kRequiresDrive + "'");
      }
      (key == "description" ? file.description : file.requires_data) = std::move(text);
      continue;
    }
    OptionValue option{key, {}, value.Mark().is_null() ? 0 : value.Mark().line + 1};
    if (value.IsScalar()) {
      CheckPrintable(yaml, value, where(key));
      option.values.push_back(value.Scalar());
    } else if (value.IsSequence() && value.size() > 0) {
      for (std::size_t i = 0; i < value.size(); ++i) {
        if (!value[i].IsScalar()) {
          yaml.Fail(value[i], where(key) + "[" + std::to_string(i) + "]", "found " + detail::Describe(value[i]),
                    "a value");
        }
        CheckPrintable(yaml, value[i], where(key) + "[" + std::to_string(i) + "]");
        option.values.push_back(value[i].Scalar());
      }
    } else {
      yaml.Fail(value, where(key), "found " + detail::Describe(value), "a value or a non-empty list of values");
    }
    file.options.push_back(std::move(option));
  }
  return file;
}

}  // namespace

OptionFile ReadOptionFile(const std::filesystem::path& path) {
  return ParseOptions(detail::YamlReader(detail::ReadTextFile(path, kMaxOptionFileBytes), path.string()));
}

OptionFile ParseOptionText(const std::string& text, const std::string& source) {
  return ParseOptions(detail::YamlReader(text, source));
}

YAML::Node OptionsYaml(const std::vector<OptionValue>& options) {
  YAML::Node map(YAML::NodeType::Map);
  for (const OptionValue& option : options) {
    if (option.values.size() == 1) {
      map[option.name] = option.values.front();
    } else {
      YAML::Node list(YAML::NodeType::Sequence);
      for (const std::string& value : option.values) list.push_back(value);
      list.SetStyle(YAML::EmitterStyle::Flow);
      map[option.name] = list;
    }
  }
  return map;
}

}  // namespace scenecal::io
