// trajectory.csv (FORMAT.md): T_world_base at strictly increasing times. The
// reader validates fully and throws InputError naming the file and the line.
#pragma once

#include <filesystem>
#include <string>

#include "core/trajectory.hpp"
#include "io/error.hpp"

namespace scenecal::io {

Trajectory ReadTrajectory(const std::filesystem::path& path);
// ReadTrajectory on the file's content already in memory; `name` stands for the file in messages.
Trajectory ParseTrajectory(const std::string& text, const std::string& name);
void WriteTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

}  // namespace scenecal::io
