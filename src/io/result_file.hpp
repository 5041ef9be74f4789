// The extrinsics files of FORMAT.md: ground_truth.yaml (a dataset's reference
// extrinsics) and the calibration result. The readers validate fully and throw
// InputError naming the file and the field.
#pragma once

#include <filesystem>
#include <string>

#include "core/calibration_result.hpp"
#include "core/rig.hpp"
#include "io/error.hpp"

namespace YAML {
class Node;  // yaml-cpp; include <yaml-cpp/yaml.h> to build one
}

namespace scenecal::io {

GroundTruth ReadGroundTruth(const std::filesystem::path& path);
// ReadGroundTruth on the file's content already in memory; `name` stands for the file in messages.
GroundTruth ParseGroundTruth(const std::string& text, const std::string& name);
void WriteGroundTruth(const std::filesystem::path& path, const GroundTruth& truth);

// The result file's `format` value.
inline constexpr char kCalibrationResultFormat[] = "scenecal-calibration/1";

// Result file (FORMAT.md "Calibration result"), written atomically.
void WriteCalibrationResult(const std::filesystem::path& path, const CalibrationResult& result);
// As above, with more top-level keys appended after the standard ones (e.g. a
// per-iteration `history`). extra_keys must be a mapping (or null) whose keys
// do not repeat a standard key; std::invalid_argument otherwise.
void WriteCalibrationResult(const std::filesystem::path& path, const CalibrationResult& result,
                            const YAML::Node& extra_keys);
// The YAML text WriteCalibrationResult writes (extra_keys may be null).
std::string CalibrationResultToYaml(const CalibrationResult& result, const YAML::Node* extra_keys = nullptr);
CalibrationResult ReadCalibrationResult(const std::filesystem::path& path);
CalibrationResult ParseCalibrationResult(const std::string& text, const std::string& name);  // content in memory

}  // namespace scenecal::io
