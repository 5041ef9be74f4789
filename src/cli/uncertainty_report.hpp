// `scenecal calibrate`: how well the data determine each lidar's extrinsic
// (core/uncertainty.hpp), logged, written into the result under the extra key
// `uncertainty` (a LOCAL 1-sigma, within the optimiser's basin; FORMAT.md's
// `sigma` stays unset as it would be read as the calibration's uncertainty),
// and turned into warnings where a direction is not determined.
#pragma once

#include <yaml-cpp/yaml.h>

#include "core/calibrate.hpp"
#include "core/calibration_result.hpp"

namespace scenecal::cli {

// Estimates every lidar's uncertainty at the result and adds warnings; returns
// the `uncertainty` mapping (by lidar name) for the result file. Logs with spdlog.
YAML::Node ReportUncertainty(const CalibrationInput& input, const CalibrationOptions& options,
                             CalibrationResult* result);

}  // namespace scenecal::cli
