// The presets of config/, compiled into the executable (presets.cpp is
// generated from config/*.yaml by src/cli/CMakeLists.txt).
#pragma once

#include <string>
#include <vector>

namespace scenecal::cli {

struct Preset {
  std::string name;  // config/<name>.yaml
  std::string text;  // the file's content
};

const std::vector<Preset>& Presets();

}  // namespace scenecal::cli
