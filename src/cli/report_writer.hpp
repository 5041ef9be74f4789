// `scenecal calibrate --report DIR`: the HTML report of one calibration
// (report/html_report.hpp): summary, convergence per alternation (alt), cost
// slices, overlays of the projected swathes. The pair costs are rebuilt from
// the input (the outcome carries none), so this reads no files but writes DIR.
#pragma once

#include <string>

#include "cli/uncertainty_report.hpp"
#include "core/calibrator.hpp"
#include "io/dataset.hpp"

namespace scenecal::cli {

struct CalibrationReportOptions {
  int slice_samples = 11;           // per DoF and slice set (~11 s in all for alt on the default dataset)
  int slice_alternations = 4;       // alt: slice at most this many alternations
  int overlay_scenes_per_pair = 2;  // scenes with the most projected points
  // Per lidar: the uncertainty's verdict and its reason (ReportErrorEstimate's).
  LidarVerdicts verdicts;
};

// Builds and writes DIR/report.html and its PNGs from the calibrator that
// solved `outcome` (its input's rig holds the initial guesses; its pair costs
// give the cost slices and overlays); outcome.alternating the alternating
// run's history (none for once / joint: the convergence section says so). Errors to the truth are shown when the dataset has ground truth.
// Throws std::runtime_error when writing fails. Logs progress with spdlog.
void WriteCalibrationReport(const std::string& dir, Calibrator& calibrator, const CalibrationOutcome& outcome,
                            const io::Dataset& dataset, const CalibrationReportOptions& report_options = {});

}  // namespace scenecal::cli
