// rig.yaml (FORMAT.md): the dataset's cameras, lidars and base frame. The
// reader validates fully and throws InputError naming the file and the field.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include "core/rig.hpp"
#include "io/error.hpp"

namespace YAML {
class Node;  // yaml-cpp; include <yaml-cpp/yaml.h> to build one
}

namespace scenecal::io {

Rig ReadRig(const std::filesystem::path& path);
// ReadRig on the file's content already in memory; `name` stands for the file in messages.
Rig ParseRig(const std::string& text, const std::string& name);
void WriteRig(const std::filesystem::path& path, const Rig& rig);
// As WriteRig, plus a top-level `extra:` mapping (free for users, ignored by ReadRig).
void WriteRig(const std::filesystem::path& path, const Rig& rig, const YAML::Node& extra);

// Most sensors a rig.yaml may name, per kind: far above any real rig, low
// enough that a corrupt or hostile file cannot make every later stage
// (folder listing, pairs, costs) explode.
inline constexpr std::size_t kMaxRigCameras = 64;
inline constexpr std::size_t kMaxRigLidars = 64;

// Sensor names: [A-Za-z0-9_-]+.
bool IsValidSensorName(const std::string& name);

}  // namespace scenecal::io
