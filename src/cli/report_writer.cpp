#include "cli/report_writer.hpp"

#include <chrono>
#include <optional>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "report/html_report.hpp"

namespace scenecal::cli {

namespace {

// The true T_camera_lidar of a pair: the truth's T_base_camera where it has
// one (the rig's otherwise) and its T_base_lidar; nullopt without truth.
std::optional<Eigen::Isometry3d> TrueCameraLidar(const io::Dataset& dataset, const CameraInfo& camera,
                                                 const std::string& lidar) {
  if (!dataset.ground_truth) return std::nullopt;
  const auto lidar_truth = dataset.ground_truth->T_base_lidar.find(lidar);
  if (lidar_truth == dataset.ground_truth->T_base_lidar.end()) return std::nullopt;
  const auto camera_truth = dataset.ground_truth->T_base_camera.find(camera.name);
  const Eigen::Isometry3d T_base_camera =
      camera_truth == dataset.ground_truth->T_base_camera.end() ? camera.T_base_camera : camera_truth->second;
  return T_base_camera.inverse() * lidar_truth->second;
}

// The result's T_camera_lidar of a pair: as reported for the pair, else
// through the known camera transform from the lidar's T_base_lidar.
std::optional<Eigen::Isometry3d> ResultCameraLidar(const CalibrationOutcome& outcome, const CameraInfo& camera,
                                                   const std::string& lidar) {
  for (const PairCalibration& pair : outcome.result.pairs) {
    if (pair.camera == camera.name && pair.lidar == lidar) return pair.T_camera_lidar;
  }
  for (const LidarCalibration& result : outcome.result.lidars) {
    if (result.lidar == lidar) return camera.T_camera_base() * result.T_base_lidar;
  }
  return std::nullopt;
}

}  // namespace

void WriteCalibrationReport(const std::string& dir, Calibrator& calibrator, const CalibrationOutcome& outcome,
                            const io::Dataset& dataset, const CalibrationReportOptions& report_options) {
  const auto start = std::chrono::steady_clock::now();
  const CalibrationInput& input = calibrator.Input();
  const CalibrationOptions& options = calibrator.Options();
  const AlternatingHistory* alt_or_null = outcome.alternating ? &*outcome.alternating : nullptr;
  const GroundTruth* truth = dataset.ground_truth ? &*dataset.ground_truth : nullptr;
  report::CalibrationReportData data = report::MakeCalibrationReportData(outcome, input.rig, truth);
  data.dataset = dataset.root.string();
  data.scheme = CalibrationSchemeName(options.scheme);
  data.metric = MetricKindName(options.cost.metric);
  for (report::LidarRow& row : data.lidars) {
    if (const auto it = report_options.verdicts.find(row.lidar); it != report_options.verdicts.end()) {
      row.verdict = it->second.first;
      row.verdict_reason = it->second.second;
    }
  }

  // Fig. 4: per pair, per alternation (alt only).
  if (alt_or_null != nullptr) {
    const AlternatingProblem& problem = alt_or_null->problem;
    data.alternations = alt_or_null->solved.alternations;
    for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
      const AlternatingCamera& camera = problem.cameras[static_cast<std::size_t>(problem.pairs[p].camera)];
      const std::string& lidar = problem.lidars[static_cast<std::size_t>(problem.pairs[p].lidar)].name;
      const CameraInfo* camera_info = input.rig.FindCamera(camera.name);
      std::optional<Eigen::Isometry3d> pair_truth;
      if (camera_info != nullptr) pair_truth = TrueCameraLidar(dataset, *camera_info, lidar);
      data.convergence.push_back(report::ConvergenceFromHistory(alt_or_null->solved.history, static_cast<int>(p),
                                                                camera.name + " / " + lidar, pair_truth));
    }
  }

  // Fig. 6 and 9 need each pair's cost: the calibrator's, at the result.
  report::CostSliceOptions slice_options;
  slice_options.samples = report_options.slice_samples;
  slice_options.max_alternations = report_options.slice_alternations;
  const OptimisationStage sharp{1.0, 0.0, 0};
  for (const PairReport& pair : outcome.pairs) {
    const CameraInfo* camera = input.rig.FindCamera(pair.camera);
    const std::optional<Eigen::Isometry3d> T_result = camera ? ResultCameraLidar(outcome, *camera, pair.lidar)
                                                             : std::nullopt;
    if (camera == nullptr || !T_result) continue;
    const std::string label = pair.camera + " / " + pair.lidar;
    spdlog::info("report: {}: cost slices and overlays", label);
    PairCost* cost_at_result = calibrator.PairAt(pair.camera, pair.lidar, camera->T_base_camera * *T_result);
    if (cost_at_result == nullptr) continue;
    PairCost& cost = *cost_at_result;
    const Eigen::Isometry3d& T_initial = pair.T_camera_lidar_initial;

    report::CostSlicePanel panel;
    panel.label = label;
    int alt_pair = -1;
    if (alt_or_null != nullptr) {
      const AlternatingProblem& problem = alt_or_null->problem;
      for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
        if (problem.cameras[static_cast<std::size_t>(problem.pairs[p].camera)].name == pair.camera &&
            problem.lidars[static_cast<std::size_t>(problem.pairs[p].lidar)].name == pair.lidar)
          alt_pair = static_cast<int>(p);
      }
    }
    if (alt_pair >= 0 && !alt_or_null->solved.history.empty()) {
      panel.sets = report::SampleAlternationSlices(cost, alt_or_null->solved.history, alt_pair, T_initial,
                                                   slice_options);
    } else {
      const report::TransformCost evaluate = [&cost](const Eigen::Isometry3d& T) { return cost.Evaluate(T); };
      PreparePairForStage(cost, sharp, T_initial);
      panel.sets.push_back(report::SampleCostSlices(evaluate, T_initial, slice_options));
      panel.sets.back().label = "initial guess";
      PreparePairForStage(cost, sharp, *T_result);
      panel.sets.push_back(report::SampleCostSlices(evaluate, *T_result, slice_options));
      panel.sets.back().label = "result";
    }
    data.cost_slices.push_back(std::move(panel));

    PreparePairForStage(cost, sharp, *T_result);
    for (report::OverlayFigure& figure :
         report::MakePairOverlays(cost, T_initial, *T_result, fmt::format("overlay_{}_{}", pair.camera, pair.lidar),
                                  report_options.overlay_scenes_per_pair)) {
      data.overlays.push_back(std::move(figure));
    }
  }

  report::WriteReportDirectory(dir, report::RenderCalibrationReport(data),
                               report::CalibrationReportAttachments(data));
  spdlog::info("report: wrote {}/report.html and {} overlay(s) in {:.1f} s", dir, data.overlays.size(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

}  // namespace scenecal::cli
