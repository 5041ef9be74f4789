// Option files and presets (--config, config/*.yaml, a result's options block): io::ParseOptionText.
#include "fuzz_common.hpp"
#include "io/option_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace scenecal;
  return fuzz::RunParser(data, size, [](const std::string& text) {
    const io::OptionFile file = io::ParseOptionText(text, "options.yaml");
    for (const io::OptionValue& option : file.options) {
      fuzz::Check(!option.name.empty() && option.name.front() != '-', "option named without --");
      fuzz::Check(!option.values.empty(), "at least one value");
    }
    // What OptionsYaml writes reads back as the same options.
    YAML::Emitter out;
    out << io::OptionsYaml(file.options);
    const io::OptionFile again = io::ParseOptionText(out.c_str(), "again.yaml");
    fuzz::Check(again.options.size() == file.options.size(), "round trip keeps every option");
    for (std::size_t i = 0; i < file.options.size(); ++i) {
      fuzz::Check(again.options[i].name == file.options[i].name, "round trip keeps the name");
      fuzz::Check(again.options[i].values == file.options[i].values, "round trip keeps the values");
    }
  });
}
