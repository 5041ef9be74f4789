// `scenecal calibrate`: how well the data determine each lidar's extrinsic
// (core/uncertainty.hpp), logged, written into the result under the extra key
// `uncertainty` (the local 1-sigma within the optimiser's basin) and turned
// into warnings where a direction is not determined; the global check that
// restarts from further away; and both combined (with other models'
// effect) into FORMAT.md's `sigma` and `covariance` and a verdict per lidar.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "core/calibration_result.hpp"
#include "core/calibrator.hpp"
#include "core/uncertainty.hpp"

namespace scenecal::cli {

// Per lidar: its verdict ("good", "weak", "unreliable") and the reason, empty when good.
using LidarVerdicts = std::map<std::string, std::pair<std::string, std::string>>;

// Estimates every lidar's uncertainty at the result, on the calibrator's pair
// costs, and adds warnings; returns the `uncertainty` mapping (by lidar name)
// for the result file. Logs with spdlog.
// basin_checks: the basin check's results (ReportBasinCheck), empty when it
// did not run; a checked lidar's local search leaves the other basins to it.
// *estimates: the estimates themselves, per lidar of the result.
YAML::Node ReportUncertainty(Calibrator& calibrator, const std::vector<LidarBasinCheck>& basin_checks,
                             CalibrationResult* result, std::vector<LidarUncertainty>* estimates);

// The global check (core/basin_check.hpp): restarts from the answer turned
// +-offset_deg about each base axis; with `adopt`, a restart that ends apart at
// a lower cost becomes the answer in *result (Calibrator::AdoptBetterRestarts);
// logs each, adds a warning per lidar whose answer changed or whose restarts
// do not come back, and returns the `basin_check` mapping (by lidar name) for
// the result file. Run it before the uncertainty, which is then at the answer.
// *checks: the checks themselves, per lidar of the result.
// scale_sigma: the trajectory's scale error (1 sigma, fraction; 0: not
// measured), whose effect on the answer the check measures with one more run
// (BasinCheckOptions::scale_sigma). without_drift_model: one more run with the
// drift corrections removed (BasinCheckOptions::without_drift_model), whose
// end ReportErrorEstimate takes as the answer under the other model when no
// other answer was solved for.
YAML::Node ReportBasinCheck(Calibrator& calibrator, double offset_deg, bool adopt, double scale_sigma,
                            bool without_drift_model, CalibrationResult* result,
                            std::vector<LidarBasinCheck>* checks);

// Per lidar, its answer under another model that the final answer replaced,
// and what that answer was (for the result's sigma_method).
struct OtherAnswers {
  std::map<std::string, Eigen::Isometry3d> by_lidar;
  std::string are;  // "the answer without the drift model", ...
};

// The error estimate per lidar (core EstimateLidarError) from the local
// estimates, the basin checks (empty: none ran) and other answers of the same
// data under another model; sets each lidar's `sigma`
// and `covariance`, logs the verdict, adds a warning for any but `good`, and
// adds `sigma`, `verdict` and the parts to each lidar's entry of *uncertainty;
// *verdicts gets each estimated lidar's verdict (for the report).
void ReportErrorEstimate(const std::vector<LidarUncertainty>& estimates, const std::vector<LidarBasinCheck>& checks,
                         const OtherAnswers& other_answers, bool trajectory_drifts, CalibrationResult* result,
                         YAML::Node* uncertainty, LidarVerdicts* verdicts);

}  // namespace scenecal::cli
