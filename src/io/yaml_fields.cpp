#include "io/yaml_fields.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <system_error>
#include <utility>

#include <fmt/format.h>
#include <yaml-cpp/depthguard.h>

#include "io/error.hpp"

namespace scenecal::io::detail {

namespace fs = std::filesystem;

void Fail(const std::string& file, const std::string& where, const std::string& what, const std::string& expected) {
  throw InputError(fmt::format("{}: {}: {}; expected {}", file, where, what, expected));
}

std::string ReadTextFile(const fs::path& path, std::size_t max_bytes) {
  std::error_code error;
  const auto status = fs::status(path, error);
  if (error && error != std::errc::no_such_file_or_directory) {  // e.g. a symlink loop (ELOOP)
    Fail(path.string(), "file", "cannot be read (" + error.message() + ")", "a readable file");
  }
  if (!fs::exists(status)) Fail(path.string(), "file", "missing", "the file to exist");
  if (!fs::is_regular_file(status)) Fail(path.string(), "file", "not a regular file", "a regular file");
  const auto size = fs::file_size(path, error);
  if (error) Fail(path.string(), "file", "cannot read its size (" + error.message() + ")", "a readable file");
  if (size > max_bytes) {
    Fail(path.string(), "file", fmt::format("{} bytes", size), fmt::format("at most {} bytes", max_bytes));
  }
  std::ifstream stream(path, std::ios::binary);
  if (!stream) Fail(path.string(), "file", "cannot be opened", "a readable file");
  std::string content(static_cast<std::size_t>(size), '\0');
  stream.read(content.data(), static_cast<std::streamsize>(size));
  content.resize(static_cast<std::size_t>(stream.gcount()));
  return content;
}

std::string FormatNumber(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  if (value == 0.0) return "0";  // no "-0" in files
  return fmt::format("{}", value);
}

YamlReader::YamlReader(const fs::path& path) : YamlReader(ReadTextFile(path, 64u << 20), path.string()) {}

std::size_t FirstInvalidUtf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto lead = static_cast<unsigned char>(text[i]);
    if (lead < 0x80) {
      ++i;
      continue;
    }
    std::size_t length = 0;
    unsigned char lowest = 0x80, highest = 0xBF;  // the range of the second byte
    if (lead >= 0xC2 && lead <= 0xDF) {
      length = 2;
    } else if (lead >= 0xE0 && lead <= 0xEF) {
      length = 3;
      if (lead == 0xE0) lowest = 0xA0;   // overlong
      if (lead == 0xED) highest = 0x9F;  // surrogates
    } else if (lead >= 0xF0 && lead <= 0xF4) {
      length = 4;
      if (lead == 0xF0) lowest = 0x90;   // overlong
      if (lead == 0xF4) highest = 0x8F;  // past U+10FFFF
    } else {
      return i;
    }
    if (length > text.size() - i) return i;
    for (std::size_t k = 1; k < length; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      if (next < (k == 1 ? lowest : 0x80) || next > (k == 1 ? highest : 0xBF)) return i;
    }
    i += length;
  }
  return std::string_view::npos;
}

YamlReader::YamlReader(const std::string& text, std::string name) : file_(std::move(name)) {
  // YAML text is Unicode; yaml-cpp passes other bytes through unchecked, and
  // its emitter would then write them differently from how they were read.
  if (const std::size_t bad = FirstInvalidUtf8(text); bad != std::string_view::npos) {
    const auto line = std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(bad), '\n') + 1;
    detail::Fail(file_, fmt::format("line {}", line),
                 fmt::format("byte {} (0x{:02X}) is not UTF-8", bad, static_cast<unsigned char>(text[bad])),
                 "a UTF-8 text file");
  }
  // Nor are control characters other than tab and line breaks YAML text (yaml-cpp reads a NUL as part of
  // other characters, so a value would not read back as it was written). A CR only ends a line before an LF:
  // alone, yaml-cpp keeps it inside a name, which then does not read back (found by fuzz_calibration_result).
  std::size_t at = 0;
  const auto is_control = [&](char c) {
    const std::size_t i = at++;
    if (c == '\r') return i + 1 >= text.size() || text[i + 1] != '\n';
    return IsControlCharacter(c) && c != '\t' && c != '\n';
  };
  if (const auto control = std::find_if(text.begin(), text.end(), is_control); control != text.end()) {
    const auto line = std::count(text.begin(), control, '\n') + 1;
    detail::Fail(file_, fmt::format("line {}", line),
                 fmt::format("byte {} (0x{:02X}) is a control character", control - text.begin(),
                             static_cast<unsigned char>(*control)),
                 "YAML text (no control characters but tab and line breaks, LF or CRLF)");
  }
  try {
    root_ = YAML::Load(text);
  } catch (const YAML::DeepRecursion& e) {  // yaml-cpp's own message is just "bad file"
    const std::string where = e.mark.is_null() ? std::string("YAML") : fmt::format("line {}", e.mark.line + 1);
    detail::Fail(file_, where, fmt::format("lists or mappings nested {} deep", e.depth()), "YAML nested less deeply");
  } catch (const YAML::Exception& e) {
    const std::string where = e.mark.is_null() ? std::string("YAML") : fmt::format("line {}", e.mark.line + 1);
    detail::Fail(file_, where, "YAML syntax error: " + e.msg, "valid YAML");
  }
}

std::string Describe(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "nothing (null)";
  if (node.IsScalar()) {
    std::string value = node.Scalar();
    if (value.size() > 40) value = value.substr(0, 40) + "...";
    return "'" + value + "'";
  }
  if (node.IsSequence()) return fmt::format("a list of {} item(s)", node.size());
  if (node.IsMap()) return "a mapping";
  return "an unknown node";
}

void YamlReader::Fail(const YAML::Node& node, const std::string& field, const std::string& what,
                      const std::string& expected) const {
  std::string where = field.empty() ? std::string("top level") : field;
  if (node.IsDefined() && !node.Mark().is_null()) where += fmt::format(" (line {})", node.Mark().line + 1);
  detail::Fail(file_, where, what, expected);
}

void YamlReader::RequireMap(const YAML::Node& node, const std::string& field) const {
  if (!node.IsMap()) Fail(node, field, "found " + Describe(node), "a mapping");
}

void YamlReader::CheckKeys(const YAML::Node& map, const std::string& field,
                           std::initializer_list<std::string_view> allowed) const {
  RequireMap(map, field);
  std::set<std::string> seen;
  for (const auto& entry : map) {
    const YAML::Node& key = entry.first;
    const std::string prefix = field.empty() ? "" : field + ".";
    if (!key.IsScalar()) Fail(key, field, "a key that is " + Describe(key), "plain names as keys");
    const std::string name = key.Scalar();
    if (!seen.insert(name).second) Fail(key, prefix + name, "duplicate key", "each key once");
    bool known = false;
    std::string allowed_list;
    for (const std::string_view candidate : allowed) {
      known = known || candidate == name;
      allowed_list += (allowed_list.empty() ? "" : ", ") + std::string(candidate);
    }
    if (!known) Fail(key, prefix + name, "unknown key", "one of: " + allowed_list);
  }
}

void YamlReader::CheckUniqueKeys(const YAML::Node& map, const std::string& field) const {
  RequireMap(map, field);
  std::set<std::string> seen;
  for (const auto& entry : map) {
    const YAML::Node& key = entry.first;
    if (!key.IsScalar()) Fail(key, field, "a key that is " + Describe(key), "plain names as keys");
    if (!seen.insert(key.Scalar()).second) Fail(key, field + "." + key.Scalar(), "duplicate key", "each key once");
  }
}

YAML::Node YamlReader::Required(const YAML::Node& map, const std::string& field, const std::string& key) const {
  const YAML::Node& const_map = map;
  YAML::Node value = const_map[key];
  const std::string where = field.empty() ? key : field + "." + key;
  if (!value.IsDefined()) Fail(map, where, "missing", "the key '" + key + "'");
  return value;
}

void YamlReader::CheckFormat(const YAML::Node& root, const char* expected) const {
  const YAML::Node format = Required(root, "", "format");
  if (String(format, "format") != expected) Fail(format, "format", "found " + Describe(format), expected);
}

std::string YamlReader::String(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) Fail(node, field, "found " + Describe(node), "a text value");
  // The file is UTF-8 (checked on reading), but yaml-cpp decodes the escapes
  // "\N" and "\_" to single Latin-1 bytes: such text would not survive being
  // written back, so it is refused here rather than changed.
  if (FirstInvalidUtf8(node.Scalar()) != std::string_view::npos) {
    Fail(node, field, "text that is not UTF-8 (from an escape)", "UTF-8 text");
  }
  return node.Scalar();
}

double YamlReader::Number(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) Fail(node, field, "found " + Describe(node), "a number");
  double value = 0.0;
  try {
    value = node.as<double>();
  } catch (const YAML::Exception&) {
    Fail(node, field, "found " + Describe(node), "a number");
  }
  if (!std::isfinite(value)) Fail(node, field, "found " + Describe(node), "a finite number");
  return value;
}

long long YamlReader::Integer(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) Fail(node, field, "found " + Describe(node), "an integer");
  try {
    return node.as<long long>();
  } catch (const YAML::Exception&) {
    Fail(node, field, "found " + Describe(node), "an integer");
  }
}

std::vector<double> YamlReader::Numbers(const YAML::Node& node, const std::string& field) const {
  if (!node.IsSequence()) Fail(node, field, "found " + Describe(node), "a list of numbers");
  std::vector<double> values;
  values.reserve(node.size());
  for (std::size_t i = 0; i < node.size(); ++i) {
    values.push_back(Number(node[i], fmt::format("{}[{}]", field, i)));
  }
  return values;
}

Eigen::Isometry3d YamlReader::Transform(const YAML::Node& node, const std::string& field) const {
  const std::string expected =
      "6 numbers [x, y, z, roll, pitch, yaw] (m, rad) or a 4x4 row-major rigid matrix [[r00, r01, r02, tx], ..., "
      "[0, 0, 0, 1]]";
  if (!node.IsSequence()) Fail(node, field, "found " + Describe(node), expected);
  if (node.size() == 4 && node[0].IsSequence()) {
    Eigen::Matrix4d matrix;
    for (std::size_t row = 0; row < 4; ++row) {
      const std::string row_field = fmt::format("{}[{}]", field, row);
      const std::vector<double> values = Numbers(node[row], row_field);
      if (values.size() != 4) {
        Fail(node[row], row_field, fmt::format("a row of {} numbers", values.size()), "4 numbers per row");
      }
      for (int col = 0; col < 4; ++col) matrix(static_cast<int>(row), col) = values[static_cast<std::size_t>(col)];
    }
    if ((matrix.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
      Fail(node, field, "last row is not [0, 0, 0, 1]", "a rigid 4x4 matrix");
    }
    if (!IsRigid(matrix, 1e-6)) {
      Fail(node, field, "the 3x3 block is not a rotation (not orthonormal or determinant not +1, tolerance 1e-6)",
           "a rigid 4x4 matrix");
    }
    Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
    transform.matrix() = matrix;
    return transform;
  }
  const std::vector<double> values = Numbers(node, field);
  if (values.size() != 6) Fail(node, field, fmt::format("{} numbers", values.size()), expected);
  return TransformFromTuple(Eigen::Map<const Vector6d>(values.data()));
}

Matrix6d YamlReader::Covariance(const YAML::Node& node, const std::string& field) const {
  const std::string expected = "a 6x6 symmetric matrix as 6 lists of 6 numbers (m and rad)";
  if (!node.IsSequence() || node.size() != 6) Fail(node, field, "found " + detail::Describe(node), expected);
  Matrix6d matrix;
  for (std::size_t row = 0; row < 6; ++row) {
    const std::string row_field = fmt::format("{}[{}]", field, row);
    const std::vector<double> values = Numbers(node[row], row_field);
    if (values.size() != 6) Fail(node[row], row_field, fmt::format("{} numbers", values.size()), expected);
    for (std::size_t column = 0; column < 6; ++column) matrix(row, column) = values[column];
  }
  for (int row = 0; row < 6; ++row) {
    if (matrix(row, row) < 0.0) {
      Fail(node[row], fmt::format("{}[{}][{}]", field, row, row), fmt::format("a negative variance {}", matrix(row, row)),
           expected);
    }
    for (int column = 0; column < row; ++column) {
      const double a = matrix(row, column), b = matrix(column, row);
      if (std::abs(a - b) > 1e-9 * std::max({std::abs(a), std::abs(b), 1e-300})) {
        Fail(node[row], fmt::format("{}[{}][{}]", field, row, column),
             fmt::format("{} against {} at [{}][{}]", a, b, column, row), expected);
      }
    }
  }
  return matrix;
}

Vector6d YamlReader::Sigma(const YAML::Node& node, const std::string& field) const {
  const std::vector<double> values = Numbers(node, field);
  if (values.size() != 6) {
    Fail(node, field, fmt::format("{} numbers", values.size()), "6 non-negative numbers (m, m, m, rad, rad, rad)");
  }
  for (std::size_t i = 0; i < 6; ++i) {
    if (values[i] < 0) {
      Fail(node[i], fmt::format("{}[{}]", field, i), fmt::format("negative value {}", values[i]),
           "6 non-negative numbers (m, m, m, rad, rad, rad)");
    }
  }
  return Eigen::Map<const Vector6d>(values.data());
}

void EmitNumbers(YAML::Emitter& out, const double* values, std::size_t count) {
  out << YAML::Flow << YAML::BeginSeq;
  for (std::size_t i = 0; i < count; ++i) out << FormatNumber(values[i]);
  out << YAML::EndSeq;
}

void EmitTransform(YAML::Emitter& out, const Eigen::Isometry3d& transform) {
  // 12 significant digits (picometres, picoradians): the matrix -> tuple ->
  // matrix trip adds ~1e-16 of noise, which shortest-digit output would carry
  // into the file, so reading and re-writing a file would not reproduce it.
  const Vector6d tuple = TupleFromTransform(transform);
  out << YAML::Flow << YAML::BeginSeq;
  for (int i = 0; i < 6; ++i) {
    out << (tuple[i] == 0.0 || !std::isfinite(tuple[i]) ? FormatNumber(tuple[i]) : fmt::format("{:.12g}", tuple[i]));
  }
  out << YAML::EndSeq;
}

}  // namespace scenecal::io::detail
