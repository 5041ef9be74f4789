#include "io/trajectory_file.hpp"

#include <array>
#include <cmath>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "core/geometry.hpp"
#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::Fail;

namespace {

constexpr char kTrajectoryHeader[] = "timestamp_us,x,y,z,qx,qy,qz,qw";
// Largest trajectory.csv read (bytes).
constexpr std::size_t kMaxTrajectoryFileBytes = std::size_t{4} << 30;

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r')) text.remove_suffix(1);
  return text;
}

template <typename T>
bool ParseWhole(std::string_view text, T* value) {
  text = Trim(text);
  return !text.empty() && detail::ParseWholeToken(text, value);
}

}  // namespace

Trajectory ReadTrajectory(const fs::path& path) {
  return ParseTrajectory(detail::ReadTextFile(path, kMaxTrajectoryFileBytes), path.string());
}

Trajectory ParseTrajectory(const std::string& text, const std::string& file) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  std::size_t line_number = 0;
  std::size_t pos = 0;
  bool seen_blank = false;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string_view line = Trim(std::string_view(text).substr(pos, end - pos));
    pos = end + 1;
    ++line_number;
    const std::string where = fmt::format("line {}", line_number);
    if (line_number == 1) {
      if (line != kTrajectoryHeader) {
        Fail(file, where, fmt::format("header '{}'", line.substr(0, 80)),
             std::string("the header ") + kTrajectoryHeader);
      }
      continue;
    }
    if (line.empty()) {
      seen_blank = true;  // trailing blank lines are harmless; blank lines between rows are not
      continue;
    }
    if (seen_blank) Fail(file, fmt::format("line {}", line_number - 1), "blank line between rows", "no blank lines");
    std::array<std::string_view, 8> fields;
    std::size_t count = 0;
    std::size_t field_start = 0;
    while (true) {
      const std::size_t comma = line.find(',', field_start);
      if (count < fields.size()) {
        fields[count] = line.substr(field_start, comma == std::string_view::npos ? line.npos : comma - field_start);
      }
      ++count;
      if (comma == std::string_view::npos) break;
      field_start = comma + 1;
    }
    if (count != 8) Fail(file, where, fmt::format("{} fields", count), "8 fields: timestamp_us,x,y,z,qx,qy,qz,qw");
    TimeUs t_us = 0;
    if (!ParseWhole(fields[0], &t_us)) {
      Fail(file, where + " timestamp_us", fmt::format("'{}'", fields[0].substr(0, 40)),
           "an int64 number of microseconds");
    }
    static constexpr const char* kNames[8] = {"timestamp_us", "x", "y", "z", "qx", "qy", "qz", "qw"};
    double values[8] = {};
    for (std::size_t i = 1; i < 8; ++i) {
      if (!ParseWhole(fields[i], &values[i]) || !std::isfinite(values[i])) {
        Fail(file, where + " " + kNames[i], fmt::format("'{}'", fields[i].substr(0, 40)), "a finite number");
      }
    }
    if (!times.empty() && t_us <= times.back()) {
      Fail(file, where + " timestamp_us", fmt::format("{} after {}", t_us, times.back()),
           "strictly increasing timestamps");
    }
    Eigen::Quaterniond rotation(values[7], values[4], values[5], values[6]);
    const double norm = rotation.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      Fail(file, where + " qx,qy,qz,qw", fmt::format("a quaternion of norm {}", norm),
           "a unit quaternion (within 1e-3)");
    }
    rotation.normalize();
    times.push_back(t_us);
    poses.push_back(TransformFromQuaternion(rotation, Eigen::Vector3d(values[1], values[2], values[3])));
  }
  if (line_number == 0) Fail(file, "line 1", "empty file", std::string("the header ") + kTrajectoryHeader);
  if (times.empty()) Fail(file, "line 2", "no pose rows", "at least one row after the header");
  return Trajectory(std::move(times), std::move(poses));
}

void WriteTrajectory(const fs::path& path, const Trajectory& trajectory) {
  std::string text = std::string(kTrajectoryHeader) + "\n";
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const Eigen::Isometry3d& pose = trajectory.poses()[i];
    const Eigen::Quaterniond q(pose.rotation());
    const Eigen::Vector3d t = pose.translation();
    text += fmt::format("{},{},{},{},{},{},{},{}\n", trajectory.times_us()[i], t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
                        q.w());
  }
  WriteFileAtomically(path.string(), text);
}

}  // namespace scenecal::io
