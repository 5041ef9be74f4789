// Internal to io: strict reading of YAML files with messages that name the
// file, the field (dotted path) and its line, what was found and what was
// expected. Not part of the public io API.
#pragma once

#include <charconv>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include "core/geometry.hpp"

namespace scenecal::io::detail {

// Throws InputError "<file>: <where>: <what>; expected <expected>".
[[noreturn]] void Fail(const std::string& file, const std::string& where, const std::string& what,
                       const std::string& expected);

// Parses the whole token as a number (nothing before or after it, no spaces).
template <typename T>
bool ParseWholeToken(std::string_view token, T* value) {
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return error == std::errc() && end == token.data() + token.size();
}

// Reads a whole file into memory, refusing files larger than max_bytes (so a
// wrong path to a huge file cannot exhaust memory). Missing file -> InputError.
std::string ReadTextFile(const std::filesystem::path& path, std::size_t max_bytes);

// Offset of the first byte that does not belong to well-formed UTF-8 (no
// overlong forms, surrogates or code points past U+10FFFF), or npos.
std::size_t FirstInvalidUtf8(std::string_view text);

// An ASCII control character (C0 or DEL): none survives a YAML round trip as itself.
inline bool IsControlCharacter(char c) {
  const auto byte = static_cast<unsigned char>(c);
  return byte < 0x20 || byte == 0x7F;
}

// Shortest decimal form that reads back to the same double ("{}" of fmt);
// non-finite values in YAML spelling (.nan, .inf, -.inf).
std::string FormatNumber(double value);

class YamlReader {
 public:
  // Loads and parses the file; a syntax error reports its line.
  explicit YamlReader(const std::filesystem::path& path);
  // Parses YAML text already in memory; `name` stands for the file in messages.
  YamlReader(const std::string& text, std::string name);

  const YAML::Node& root() const { return root_; }
  const std::string& file() const { return file_; }

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& field, const std::string& what,
                         const std::string& expected) const;

  void RequireMap(const YAML::Node& node, const std::string& field) const;
  // Every key of the mapping must be a scalar, appear once and be in allowed.
  void CheckKeys(const YAML::Node& map, const std::string& field,
                 std::initializer_list<std::string_view> allowed) const;
  // A mapping whose keys are scalars, each once (names chosen by the user).
  void CheckUniqueKeys(const YAML::Node& map, const std::string& field) const;
  // map[key] (map already checked); missing -> error naming field.key.
  YAML::Node Required(const YAML::Node& map, const std::string& field, const std::string& key) const;

  std::string String(const YAML::Node& node, const std::string& field) const;
  // The root's `format` key, which must be `expected` (e.g. "scenecal-dataset/1").
  void CheckFormat(const YAML::Node& root, const char* expected) const;
  double Number(const YAML::Node& node, const std::string& field) const;  // finite
  long long Integer(const YAML::Node& node, const std::string& field) const;
  std::vector<double> Numbers(const YAML::Node& node, const std::string& field) const;  // finite
  // 6-tuple [x y z roll pitch yaw] or a rigid 4x4 row-major nested list.
  Eigen::Isometry3d Transform(const YAML::Node& node, const std::string& field) const;
  // 6 rows of 6 finite numbers, symmetric (to 1e-9 relative) with a non-negative diagonal.
  Matrix6d Covariance(const YAML::Node& node, const std::string& field) const;
  // Six non-negative numbers.
  Vector6d Sigma(const YAML::Node& node, const std::string& field) const;

 private:
  std::string file_;
  YAML::Node root_;
};

// What a node holds, for "found ..." in messages.
std::string Describe(const YAML::Node& node);

// Emits a transform in the 6-number form with 12 significant digits.
void EmitTransform(YAML::Emitter& out, const Eigen::Isometry3d& transform);
void EmitNumbers(YAML::Emitter& out, const double* values, std::size_t count);

}  // namespace scenecal::io::detail
