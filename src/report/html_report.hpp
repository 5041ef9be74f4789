// Self-contained HTML reports a person reads: one file with inline CSS, inline
// SVG plots and PNG overlays as data: URIs; no external reference of any kind
// (no http(s), fonts, scripts or stylesheets), so it opens offline anywhere.
//
// Calibration report (`scenecal calibrate --report DIR`), sections by id:
//   #summary      result per lidar (T_base_lidar) and per pair (T_camera_lidar)
//                 as 6-tuples in cm / deg, costs, scenes, optimiser runs
//                 (iterations, evaluations, time), termination, warnings,
//                 settings; per-axis error to ground truth when given.
//   #convergence  the paper's Fig. 4: per pair, per DoF, lower and upper
//                 solution per alternation (error to the truth when known,
//                 the value otherwise), and the lower-level cost.
//   #cost-slices  Fig. 6: the cost sampled along each DoF, light to dark per alternation.
//   #uncertainty  per lidar the verdict and a plot of the +-2 sigma interval per
//                 DoF against what counts as good (1 cm / 0.2 deg), with the
//                 error to the truth when known.
//   #overlays     Fig. 9: projected swathe, initial guess (red) vs result (blue),
//                 and coloured by reflectance; also returned as PNG attachments.
// Experiment report (`scenecal experiment`), sections by id:
//   #summary, #box-plots (Fig. 7: translation / rotation error per method),
//   #per-dof-errors (Fig. 8: absolute error per DoF per method), #runs, #overlays.
//
// Caller's side, e.g. for a calibration:
//   report::CalibrationReportData data = report::MakeCalibrationReportData(outcome, rig, truth_or_null);
//   data.dataset = path; data.scheme = "alt"; data.metric = "nid";
//   data.convergence.push_back(report::ConvergenceFromHistory(alt.history, p, "left / rear", truth_p));
//   data.cost_slices.push_back({"left / rear", report::SampleAlternationSlices(cost, alt.history, p, T0)});
//   data.overlays = report::MakePairOverlays(cost, T0, T_result, "left_rear");
//   report::WriteReportDirectory(dir, report::RenderCalibrationReport(data),
//                                report::CalibrationReportAttachments(data));
// Rendering never prints and never throws for odd data (empty sections say so;
// non-finite numbers show as "n/a"); only WriteReportDirectory touches files.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/alternating.hpp"
#include "core/calibrate.hpp"
#include "core/geometry.hpp"
#include "core/pair_cost.hpp"
#include "core/rig.hpp"
#include "report/cost_slices.hpp"
#include "report/overlay.hpp"

namespace scenecal::report {

// Per-axis error in the 6-tuple parameterisation: tuple(estimate) - tuple(truth),
// [m, m, m, rad, rad, rad], angle differences wrapped to (-pi, pi].
Vector6d TupleError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth);

// A file written next to the page (name relative to the report directory).
struct ReportFile {
  std::string name;
  std::string content;  // bytes
};

struct LidarRow {
  std::string lidar;
  Eigen::Isometry3d T_base_lidar_initial = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();  // the result
  std::optional<Vector6d> sigma;                                   // 1-sigma (m, m, m, rad, rad, rad)
  std::optional<Eigen::Isometry3d> T_base_lidar_truth;
  std::string verdict;         // "good" | "weak" | "unreliable"; empty when not judged
  std::string verdict_reason;  // why it is not good, in words
};

struct PairRow {
  std::string camera;
  std::string lidar;
  Eigen::Isometry3d T_camera_lidar_initial = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_camera_lidar = Eigen::Isometry3d::Identity();  // the result
  std::optional<double> initial_cost;
  std::optional<double> final_cost;
  int scenes = 0;
  int scenes_used = 0;
  std::optional<Eigen::Isometry3d> T_camera_lidar_truth;
};

struct OptimisationRow {
  std::string problem;  // e.g. "joint rear", "alt (lower level, 4 pairs)"
  int stages = 0;
  int iterations = 0;
  int evaluations = 0;
  double seconds = 0.0;
  std::string termination;
};

// Fig. 4 for one pair: T_camera_lidar per alternation.
struct ConvergenceSeries {
  std::string label;  // e.g. "left / rear"
  std::vector<int> alternations;
  std::vector<Eigen::Isometry3d> lower;  // T^_p per alternation
  std::vector<Eigen::Isometry3d> upper;  // T_p per alternation (after the upper level)
  std::vector<double> lower_cost;        // f_p at the lower solution, per alternation (may be empty)
  std::optional<Eigen::Isometry3d> truth;
};

// Fig. 6 for one pair: slice sets drawn light (first) to dark (last).
struct CostSlicePanel {
  std::string label;
  std::vector<CostSliceSet> sets;
};

// Fig. 9 and friends: an image (BGR CV_8UC3) shown inline and saved as file_name.
struct OverlayFigure {
  std::string title;
  std::string caption;
  std::string file_name;  // e.g. "overlay_left_rear_0.png"; made safe when written
  cv::Mat bgr;
};

struct CalibrationReportData {
  std::string title = "scenecal calibration report";
  std::string dataset;  // path or name, shown as given
  std::string scheme;   // "once" | "joint" | "alt"
  std::string metric;   // "nid" | "mi"
  std::vector<LidarRow> lidars;
  std::vector<PairRow> pairs;
  std::vector<OptimisationRow> optimisations;
  int alternations = 0;  // alt only
  std::string termination;
  std::vector<std::string> warnings;
  std::map<std::string, std::string> settings;
  std::map<std::string, double> timings_s;
  std::vector<ConvergenceSeries> convergence;
  std::vector<CostSlicePanel> cost_slices;
  std::vector<OverlayFigure> overlays;
};

// Summary tables from an outcome: lidars (initial from the rig), pairs (costs,
// scenes, initial guess), optimiser runs, termination, warnings, settings,
// timings. With `truth`, the true T_base_lidar and T_camera_lidar =
// T_base_camera^-1 * T_base_lidar (the true T_base_camera where the truth has
// one, the rig's otherwise).
CalibrationReportData MakeCalibrationReportData(const CalibrationOutcome& outcome, const Rig& rig,
                                                const GroundTruth* truth = nullptr);

// Fig. 4 data of one pair (index into the records' per-pair vectors).
ConvergenceSeries ConvergenceFromHistory(const std::vector<AlternationRecord>& history, int pair,
                                         const std::string& label,
                                         const std::optional<Eigen::Isometry3d>& truth = std::nullopt);

// Overlays for one pair: for up to max_scenes scenes (those with the most
// projected points at the result), Fig. 9 (initial red, result blue) and the
// result coloured by reflectance. file_stem prefixes the PNG names.
std::vector<OverlayFigure> MakePairOverlays(const PairCost& cost, const Eigen::Isometry3d& T_camera_lidar_initial,
                                            const Eigen::Isometry3d& T_camera_lidar_result,
                                            const std::string& file_stem, int max_scenes = 1,
                                            const OverlayOptions& options = {});

std::string RenderCalibrationReport(const CalibrationReportData& data);
// The overlay PNGs (named by OverlayFigure::file_name, made safe).
std::vector<ReportFile> CalibrationReportAttachments(const CalibrationReportData& data);

// One calibration of an experiment, compared with the truth.
struct ExperimentRun {
  std::string method;  // group label, e.g. "alt-nid", "once-mi", "joint-nid"
  std::string lidar;
  int trial = 0;
  bool success = true;
  std::string termination;
  Vector6d error = Vector6d::Zero();  // TupleError(estimate, truth): m, m, m, rad, rad, rad
  double translation_error_m = 0.0;   // TranslationError
  double rotation_error_deg = 0.0;    // RotationErrorDegrees
  double seconds = 0.0;
};

ExperimentRun MakeExperimentRun(const std::string& method, const std::string& lidar, int trial,
                                const Eigen::Isometry3d& T_base_lidar_estimate,
                                const Eigen::Isometry3d& T_base_lidar_truth, double seconds, bool success = true,
                                const std::string& termination = "");

struct ExperimentReportData {
  std::string title = "scenecal experiment report";
  std::string description;               // free text, shown as a paragraph
  std::vector<std::string> methods;      // display order; empty = order of first appearance in runs
  std::vector<std::string> per_dof_methods;  // Fig. 8 methods (the paper: alt-nid vs mi); empty = all
  std::vector<ExperimentRun> runs;
  std::map<std::string, std::string> settings;
  std::vector<OverlayFigure> overlays;
};

std::string RenderExperimentReport(const ExperimentReportData& data);
std::vector<ReportFile> ExperimentReportAttachments(const ExperimentReportData& data);

// Creates `directory` (and parents) and writes the page as html_name plus the
// attachments next to it, each with io::WriteFileAtomically. Throws
// std::runtime_error (from the io layer or the filesystem) on failure.
void WriteReportDirectory(const std::string& directory, const std::string& html,
                          const std::vector<ReportFile>& attachments, const std::string& html_name = "report.html");

// A file name with only [A-Za-z0-9._-] (others become '_'), never empty.
std::string SafeFileName(const std::string& name);

}  // namespace scenecal::report
