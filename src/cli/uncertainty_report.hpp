// `scenecal calibrate`: how well the data determine each lidar's extrinsic
// (core/uncertainty.hpp), logged, written into the result under the extra key
// `uncertainty` (a LOCAL 1-sigma, within the optimiser's basin; FORMAT.md's
// `sigma` stays unset as it would be read as the calibration's uncertainty),
// and turned into warnings where a direction is not determined; and the
// global check that restarts from further away.
#pragma once

#include <yaml-cpp/yaml.h>

#include "core/calibration_result.hpp"
#include "core/calibrator.hpp"

namespace scenecal::cli {

// Estimates every lidar's uncertainty at the result, on the calibrator's pair
// costs, and adds warnings; returns the `uncertainty` mapping (by lidar name)
// for the result file. Logs with spdlog.
YAML::Node ReportUncertainty(Calibrator& calibrator, CalibrationResult* result);

// The global check (core/basin_check.hpp): restarts from the answer turned
// +-offset_deg about each base axis; logs each, adds a warning per lidar whose
// restarts do not come back, and returns the `basin_check` mapping (by lidar
// name) for the result file.
YAML::Node ReportBasinCheck(Calibrator& calibrator, double offset_deg, CalibrationResult* result);

}  // namespace scenecal::cli
