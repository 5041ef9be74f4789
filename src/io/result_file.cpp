#include "io/result_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>
#include <vector>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;
using detail::FormatNumber;
using detail::YamlReader;

namespace {

constexpr char kGroundTruthFormat[] = "scenecal-ground-truth/1";
// Largest ground_truth.yaml or result file read (bytes).
constexpr std::size_t kMaxYamlFileBytes = std::size_t{64} << 20;

}  // namespace

// ---- ground_truth.yaml -----------------------------------------------------------

GroundTruth ReadGroundTruth(const fs::path& path) {
  return ParseGroundTruth(detail::ReadTextFile(path, kMaxYamlFileBytes), path.string());
}

GroundTruth ParseGroundTruth(const std::string& text, const std::string& name) {
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.CheckKeys(root, "", {"format", "lidars", "cameras"});
  yaml.CheckFormat(root, kGroundTruthFormat);
  GroundTruth truth;
  const YAML::Node lidars = yaml.Required(root, "", "lidars");
  yaml.CheckUniqueKeys(lidars, "lidars");
  for (const auto& entry : lidars) {
    const std::string lidar = entry.first.Scalar();
    yaml.CheckKeys(entry.second, "lidars." + lidar, {"T_base_lidar"});
    truth.T_base_lidar[lidar] = yaml.Transform(yaml.Required(entry.second, "lidars." + lidar, "T_base_lidar"),
                                               "lidars." + lidar + ".T_base_lidar");
  }
  if (const YAML::Node cameras = root["cameras"]; cameras.IsDefined() && !cameras.IsNull()) {
    yaml.CheckUniqueKeys(cameras, "cameras");
    for (const auto& entry : cameras) {
      const std::string camera = entry.first.Scalar();
      yaml.CheckKeys(entry.second, "cameras." + camera, {"T_base_camera"});
      truth.T_base_camera[camera] = yaml.Transform(yaml.Required(entry.second, "cameras." + camera, "T_base_camera"),
                                                   "cameras." + camera + ".T_base_camera");
    }
  }
  return truth;
}

namespace {

// `key: {name: {transform_key: [x, y, z, roll, pitch, yaw]}, ...}`
void EmitTransformMap(YAML::Emitter& out, const char* key, const char* transform_key,
                      const std::map<std::string, Eigen::Isometry3d>& transforms) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  for (const auto& [name, transform] : transforms) {
    out << YAML::Key << name << YAML::Value << YAML::BeginMap << YAML::Key << transform_key << YAML::Value;
    detail::EmitTransform(out, transform);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
}

}  // namespace

void WriteGroundTruth(const fs::path& path, const GroundTruth& truth) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kGroundTruthFormat;
  EmitTransformMap(out, "lidars", "T_base_lidar", truth.T_base_lidar);
  if (!truth.T_base_camera.empty()) EmitTransformMap(out, "cameras", "T_base_camera", truth.T_base_camera);
  out << YAML::EndMap;
  WriteFileAtomically(path.string(), std::string(out.c_str()) + "\n");
}

// ---- calibration result -----------------------------------------------------------------

namespace {

// A key as plain text when it is a simple name (what scenecal writes, and what
// scripts grep for), else double-quoted with escapes: a key read from an escape
// such as "\r" must not be written back raw (found by fuzz_calibration_result).
void EmitKey(YAML::Emitter& out, const std::string& key) {
  const auto name_character = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_' || c == '-' || c == '.';
  };
  const bool plain = !key.empty() && (std::isalpha(static_cast<unsigned char>(key.front())) != 0 || key.front() == '_') &&
                     std::all_of(key.begin(), key.end(), name_character);
  out << YAML::Key;
  if (!plain) out << YAML::DoubleQuoted;
  out << key;
}

}  // namespace

std::string CalibrationResultToYaml(const CalibrationResult& result, const YAML::Node* extra_keys) {
  static const std::set<std::string> kStandardKeys = {"format", "lidars", "pairs", "termination",
                                                      "settings", "timings_s", "warnings"};
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kCalibrationResultFormat;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginMap;
  for (const LidarCalibration& lidar : result.lidars) {
    out << YAML::Key << lidar.lidar << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "T_base_lidar" << YAML::Value;
    detail::EmitTransform(out, lidar.T_base_lidar);
    if (lidar.sigma) {
      out << YAML::Key << "sigma" << YAML::Value;
      detail::EmitNumbers(out, lidar.sigma->data(), 6);
    }
    if (lidar.covariance) {
      out << YAML::Key << "covariance" << YAML::Value << YAML::BeginSeq;
      for (int row = 0; row < 6; ++row) {
        const Vector6d values = lidar.covariance->row(row).transpose();
        detail::EmitNumbers(out, values.data(), 6);
      }
      out << YAML::EndSeq;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::Key << "pairs" << YAML::Value << YAML::BeginSeq;
  for (const PairCalibration& pair : result.pairs) {
    out << YAML::BeginMap;
    out << YAML::Key << "camera" << YAML::Value << pair.camera;
    out << YAML::Key << "lidar" << YAML::Value << pair.lidar;
    out << YAML::Key << "T_camera_lidar" << YAML::Value;
    detail::EmitTransform(out, pair.T_camera_lidar);
    out << YAML::Key << "cost" << YAML::Value << FormatNumber(pair.cost);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "termination" << YAML::Value << YAML::DoubleQuoted << result.termination;
  out << YAML::Key << "settings" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : result.settings) {
    EmitKey(out, key);
    out << YAML::Value << YAML::DoubleQuoted << value;
  }
  out << YAML::EndMap;
  out << YAML::Key << "timings_s" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : result.timings_s) {
    EmitKey(out, key);
    out << YAML::Value << FormatNumber(value);
  }
  out << YAML::EndMap;
  out << YAML::Key << "warnings" << YAML::Value << YAML::BeginSeq;
  for (const std::string& warning : result.warnings) out << YAML::DoubleQuoted << warning;
  out << YAML::EndSeq;
  if (extra_keys != nullptr && extra_keys->IsDefined() && !extra_keys->IsNull()) {
    if (!extra_keys->IsMap()) {
      throw std::invalid_argument("CalibrationResultToYaml: extra keys must be a YAML mapping");
    }
    for (const auto& entry : *extra_keys) {
      const std::string key = entry.first.as<std::string>();
      if (kStandardKeys.count(key) != 0) {
        throw std::invalid_argument("CalibrationResultToYaml: extra key '" + key + "' repeats a standard key");
      }
      out << YAML::Key << key << YAML::Value << entry.second;
    }
  }
  out << YAML::EndMap;
  if (!out.good()) throw std::runtime_error("CalibrationResultToYaml: YAML emitter error: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

void WriteCalibrationResult(const fs::path& path, const CalibrationResult& result) {
  WriteFileAtomically(path.string(), CalibrationResultToYaml(result, nullptr));
}

void WriteCalibrationResult(const fs::path& path, const CalibrationResult& result, const YAML::Node& extra_keys) {
  WriteFileAtomically(path.string(), CalibrationResultToYaml(result, &extra_keys));
}

CalibrationResult ReadCalibrationResult(const fs::path& path) {
  return ParseCalibrationResult(detail::ReadTextFile(path, kMaxYamlFileBytes), path.string());
}

CalibrationResult ParseCalibrationResult(const std::string& text, const std::string& name) {
  const YamlReader yaml(text, name);
  const YAML::Node& root = yaml.root();
  yaml.RequireMap(root, "");
  yaml.CheckFormat(root, kCalibrationResultFormat);
  CalibrationResult result;
  const YAML::Node lidars = yaml.Required(root, "", "lidars");
  yaml.CheckUniqueKeys(lidars, "lidars");
  for (const auto& entry : lidars) {
    const std::string lidar_name = entry.first.Scalar();
    const std::string field = "lidars." + lidar_name;
    yaml.CheckKeys(entry.second, field, {"T_base_lidar", "sigma", "covariance"});
    LidarCalibration lidar;
    lidar.lidar = lidar_name;
    lidar.T_base_lidar = yaml.Transform(yaml.Required(entry.second, field, "T_base_lidar"), field + ".T_base_lidar");
    const YAML::Node& lidar_node = entry.second;
    if (const YAML::Node sigma = lidar_node["sigma"]; sigma.IsDefined()) {
      lidar.sigma = yaml.Sigma(sigma, field + ".sigma");
    }
    if (const YAML::Node covariance = lidar_node["covariance"]; covariance.IsDefined()) {
      lidar.covariance = yaml.Covariance(covariance, field + ".covariance");
    }
    result.lidars.push_back(std::move(lidar));
  }
  const YAML::Node pairs = yaml.Required(root, "", "pairs");
  if (!pairs.IsSequence()) yaml.Fail(pairs, "pairs", "found " + detail::Describe(pairs), "a list of pairs");
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const std::string field = fmt::format("pairs[{}]", i);
    const YAML::Node node = pairs[i];
    yaml.CheckKeys(node, field, {"camera", "lidar", "T_camera_lidar", "cost"});
    PairCalibration pair;
    pair.camera = yaml.String(yaml.Required(node, field, "camera"), field + ".camera");
    pair.lidar = yaml.String(yaml.Required(node, field, "lidar"), field + ".lidar");
    pair.T_camera_lidar = yaml.Transform(yaml.Required(node, field, "T_camera_lidar"), field + ".T_camera_lidar");
    const YAML::Node cost = yaml.Required(node, field, "cost");
    try {
      pair.cost = cost.as<double>();  // may be .nan when a pair had no data
    } catch (const YAML::Exception&) {
      yaml.Fail(cost, field + ".cost", "found " + detail::Describe(cost), "a number");
    }
    if (std::isinf(pair.cost)) {
      yaml.Fail(cost, field + ".cost", "found " + detail::Describe(cost),
                "a finite number, or .nan for a pair without data");
    }
    result.pairs.push_back(std::move(pair));
  }
  if (const YAML::Node termination = root["termination"]; termination.IsDefined()) {
    result.termination = yaml.String(termination, "termination");
  }
  if (const YAML::Node settings = root["settings"]; settings.IsDefined() && !settings.IsNull()) {
    yaml.RequireMap(settings, "settings");
    for (const auto& entry : settings) {
      const std::string key = yaml.String(entry.first, "a key of settings");
      result.settings[key] = yaml.String(entry.second, "settings." + key);
    }
  }
  if (const YAML::Node timings = root["timings_s"]; timings.IsDefined() && !timings.IsNull()) {
    yaml.RequireMap(timings, "timings_s");
    for (const auto& entry : timings) {
      result.timings_s[entry.first.Scalar()] = yaml.Number(entry.second, "timings_s." + entry.first.Scalar());
    }
  }
  if (const YAML::Node warnings = root["warnings"]; warnings.IsDefined() && !warnings.IsNull()) {
    if (!warnings.IsSequence()) {
      yaml.Fail(warnings, "warnings", "found " + detail::Describe(warnings), "a list of text");
    }
    for (std::size_t i = 0; i < warnings.size(); ++i) {
      result.warnings.push_back(yaml.String(warnings[i], fmt::format("warnings[{}]", i)));
    }
  }
  return result;
}

}  // namespace scenecal::io
