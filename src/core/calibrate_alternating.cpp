#include "core/calibrate_alternating.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>

#include <fmt/format.h>

#include "core/number_text.hpp"

namespace scenecal {
namespace {

// FNV-1a, folding values into a digest.
struct Digest {
  std::uint64_t hash = 1469598103934665603ull;
  void Add(const void* data, std::size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
      hash ^= bytes[i];
      hash *= 1099511628211ull;
    }
  }
  void Add(double value) { Add(&value, sizeof(value)); }
  void Add(std::uint64_t value) { Add(&value, sizeof(value)); }
  void Add(const std::string& text) { Add(text.data(), text.size()); }
};

}  // namespace

std::size_t StageIndexForAlternation(std::size_t stage_count, int alternation, int span) {
  return std::min(stage_count - 1,
                  static_cast<std::size_t>(alternation) * stage_count / static_cast<std::size_t>(std::max(1, span)));
}

const OptimisationStage& StageForAlternation(const std::vector<OptimisationStage>& stages, int alternation, int span) {
  return stages[StageIndexForAlternation(stages.size(), alternation, span)];
}

bool IsStageStart(std::size_t stage_count, int alternation, int span) {
  return alternation == 0 || StageIndexForAlternation(stage_count, alternation - 1, span) !=
                                 StageIndexForAlternation(stage_count, alternation, span);
}

int FirstAlternationOfLastStage(const std::vector<OptimisationStage>& stages, int span) {
  for (int i = 0; i < span; ++i) {
    if (StageIndexForAlternation(stages.size(), i, span) == stages.size() - 1) return i;
  }
  return span - 1;
}

int StageSpan(const AlternatingOptions& alternating) {
  return alternating.stage_alternations > 0 ? std::min(alternating.stage_alternations, alternating.max_alternations)
                                            : alternating.max_alternations;
}

std::optional<LevelsApart> CheckLevelsApart(const AlternatingOptions& alternating, const AlternationRecord& last,
                                            bool stopped_by_time_budget) {
  LevelsApart apart;
  apart.translation_m = last.max_disagreement_translation_m;
  apart.rotation_rad = last.max_disagreement_rotation_rad;
  if (apart.translation_m <= alternating.agreement_translation_m &&
      apart.rotation_rad <= alternating.agreement_rotation_rad) {
    return std::nullopt;
  }
  apart.sigma_translation_m = last.sigma_translation_m;
  apart.sigma_rotation_rad = last.sigma_rotation_rad;
  apart.covariance_shrink = alternating.covariance_shrink;
  if (stopped_by_time_budget) {
    apart.remedy = LevelsApart::Remedy::kLargerTimeBudget;
  } else if (StageSpan(alternating) >= alternating.max_alternations) {
    apart.remedy = LevelsApart::Remedy::kStagesOnFirstAlternations;
    apart.suggested_alternations = alternating.max_alternations + 6;
    apart.suggested_stage_alternations = alternating.max_alternations;
  } else {
    // After the stages the gap shrinks with the penalty's covariance, by w an alternation once the penalty
    // is stiffer than the cost: twice the shrinks it needs, and some; the run stops by itself once both
    // levels have settled below the stop thresholds (a known inter-camera transform 0.05 deg off: 0.018 deg
    // apart after 26, settled after 32; BENCHMARK.md, "The alternating scheme against once and joint").
    const auto ratio = [](double gap, double stop, double agreement) { return gap / (stop > 0 ? stop : agreement); };
    const double gap =
        std::max({ratio(apart.translation_m, alternating.stop_translation_m, alternating.agreement_translation_m),
                  ratio(apart.rotation_rad, alternating.stop_rotation_rad, alternating.agreement_rotation_rad), 1.0});
    const int more = static_cast<int>(std::ceil(std::log(gap) / std::log(1.0 / alternating.covariance_shrink)));
    apart.remedy = LevelsApart::Remedy::kMoreAlternations;
    apart.suggested_alternations = alternating.max_alternations + 2 * more + 4;
  }
  return apart;
}

std::string DescribeLevelsApart(const LevelsApart& apart) {
  std::string remedy;
  switch (apart.remedy) {
    case LevelsApart::Remedy::kLargerTimeBudget:
      remedy = "the time budget stopped the run; a larger one lets the penalty tighten further";
      break;
    case LevelsApart::Remedy::kStagesOnFirstAlternations:
      remedy = "more alternations with the stages kept on the first ones (e.g. " +
               std::to_string(apart.suggested_alternations) + " alternations, the stages over the first " +
               std::to_string(apart.suggested_stage_alternations) +
               ") tighten it after the stages, toward the joint scheme's answer";
      break;
    case LevelsApart::Remedy::kMoreAlternations:
      remedy = "the gap shrinks by the penalty's factor w = " + NumberText(apart.covariance_shrink) +
               " with each alternation after the stages: " + std::to_string(apart.suggested_alternations) +
               " alternations (the run stops by itself once the levels have settled) tighten it toward the joint "
               "scheme's answer";
      break;
  }
  return "alt: the lower and upper levels ended " + NumberText(apart.translation_m * 1000.0) + " mm / " +
         NumberText(DegreesFromRadians(apart.rotation_rad)) + " deg apart (penalty sigma " +
         NumberText(apart.sigma_translation_m) + " m / " + NumberText(apart.sigma_rotation_rad) +
         " rad at the end): the pairs' own minima disagree by more than the coupling had enforced, and the result "
         "is the upper level's compromise between them; " + remedy;
}

std::vector<double> StepScalesForAlternations(const std::vector<OptimisationStage>& stages, int max_alternations,
                                              int span) {
  std::vector<double> scales;
  for (int i = 0; i < max_alternations; ++i) scales.push_back(StageForAlternation(stages, i, span).step_scale);
  return scales;
}

AlternatingOptions AlternatingOptionsFor(const CalibrationOptions& options) {
  const AlternatingSettings& settings = options.alternating;
  AlternatingOptions alternating;
  alternating.max_alternations = settings.max_alternations;
  alternating.stage_alternations = settings.stage_alternations;
  alternating.covariance_shrink = settings.covariance_shrink;
  alternating.penalty_frame = settings.penalty_frame;
  alternating.stop_translation_m = settings.stop_translation_m;
  alternating.stop_rotation_rad = settings.stop_rotation_rad;
  alternating.default_camera_sigma_translation_m = settings.default_camera_sigma_translation_m;
  alternating.default_camera_sigma_rotation_rad = settings.default_camera_sigma_rotation_rad;
  alternating.agreement_translation_m = settings.agreement_translation_m;
  alternating.agreement_rotation_rad = settings.agreement_rotation_rad;
  alternating.lower = options.nelder_mead;
  alternating.lower_solver = options.lower_solver;
  alternating.lower_gradient = options.gradient;
  alternating.time_budget_s = options.time_budget_s;
  const int span = StageSpan(alternating);
  alternating.min_alternations = FirstAlternationOfLastStage(options.stages, span) + 1;
  alternating.skip_settled = settings.skip_settled;
  for (int i = 1; i < alternating.max_alternations; ++i) {
    if (IsStageStart(options.stages.size(), i, span)) alternating.stage_starts.push_back(i);
  }
  alternating.lower_step_scale = StepScalesForAlternations(options.stages, alternating.max_alternations, span);
  // The paper's P^0 goes with its simplex. L-BFGS lower levels find the smooth
  // cost's own minimum, and there the paper's coupling already holds them back
  // where the cost is flat (docs/findings.md, "The alternating scheme's penalty holds in the lidar frame").
  const double sigma0 = options.lower_solver == LowerSolver::kLbfgs ? kLbfgsInitialSigma : 5.0;
  alternating.initial_sigma_translation_m =
      settings.initial_sigma_translation_m > 0.0 ? settings.initial_sigma_translation_m : sigma0;
  alternating.initial_sigma_rotation_rad =
      settings.initial_sigma_rotation_rad > 0.0 ? settings.initial_sigma_rotation_rad : sigma0;
  return alternating;
}

std::vector<PairObjective> AlternatingSetup::Objectives(const CalibrationOptions& options,
                                                        const AlternatingOptions& alternating) {
  std::vector<PairObjective> objectives;
  for (PairCost* cost : costs) {
    PairObjective objective;
    objective.cost = [cost](const Eigen::Isometry3d& T_camera_lidar) { return cost->Evaluate(T_camera_lidar); };
    objective.cost_with_gradient = [cost](const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                                          const Eigen::Vector3d& pivot_lidar, Vector6d* gradient) {
      return cost->EvaluateWithGradient(T_camera_lidar, update, pivot_lidar, gradient);
    };
    const std::vector<OptimisationStage> stages = options.stages;
    const int span = StageSpan(alternating);
    objective.prepare = [cost, stages, span](const Eigen::Isometry3d& T_camera_lidar, int alternation) {
      PreparePairForStage(*cost, StageForAlternation(stages, alternation, span), T_camera_lidar);
    };
    objectives.push_back(std::move(objective));
  }
  return objectives;
}

LowerLevelBatchHook AlternatingSetup::BatchHook(const CalibrationOptions& options,
                                                const AlternatingOptions& alternating,
                                                const ProgressCallback& progress) {
  if (!options.motion_correction) return {};
  return [this, stages = options.stages, first_stage = options.motion_correction_first_stage,
          motion = options.motion, span = StageSpan(alternating),
          progress](const std::vector<LowerLevelTask>& tasks) {
    if (tasks.empty()) return;
    const int alternation = tasks.front().alternation;
    const std::size_t stage_index = StageIndexForAlternation(stages.size(), alternation, span);
    if (!IsStageStart(stages.size(), alternation, span) || stage_index < static_cast<std::size_t>(first_stage)) return;
    const OptimisationStage& stage = stages[stage_index];
    // Every lidar's pairs together: the drift belongs to the trajectory, so the
    // lidars' swathes of one camera frame share its correction (and the drive's scale).
    std::vector<PairCost*> pairs;
    std::vector<Eigen::Isometry3d> T_camera_lidar;
    std::vector<std::string> lidars;  // those with a pair in the batch
    for (std::size_t l = 0; l < problem.lidars.size(); ++l) {
      const std::size_t before = pairs.size();
      for (const LowerLevelTask& task : tasks) {
        const std::size_t p = static_cast<std::size_t>(task.pair);
        if (p >= costs.size() || problem.pairs[p].lidar != static_cast<int>(l)) continue;
        PreparePairForStage(*costs[p], stage, task.T_camera_lidar_upper);
        pairs.push_back(costs[p]);
        T_camera_lidar.push_back(task.T_camera_lidar_upper);
      }
      if (pairs.size() > before) lidars.push_back(problem.lidars[l].name);
    }
    if (pairs.empty()) return;
    const MotionCorrectionSummary summary = EstimateMotionCorrections(pairs, T_camera_lidar, motion);
    // Each lower level refreshes its visibility before it runs (Objectives' prepare).
    if (progress) {
      progress(fmt::format("motion correction (alternation {}, {} {}, {} pair(s)): {}", alternation + 1,
                           lidars.size() > 1 ? "lidars" : "lidar", fmt::join(lidars, ", "), pairs.size(),
                           DescribeMotionCorrection(summary)));
    }
  };
}

std::uint64_t AlternatingSetup::Fingerprint(const CalibrationOptions& options,
                                            const AlternatingOptions& alternating) const {
  Digest digest;
  for (std::size_t p = 0; p < costs.size(); ++p) {
    const PairCost& cost = *costs[p];
    digest.Add(cost.Camera().name);
    digest.Add(cost.Lidar());
    digest.Add(static_cast<std::uint64_t>(cost.SceneCount()));
    for (const SceneSwathe& scene : cost.Scenes()) {
      digest.Add(static_cast<std::uint64_t>(scene.ImageTime()));
      digest.Add(static_cast<std::uint64_t>(scene.PointCount()));
    }
    digest.Add(initial_costs[p]);
  }
  for (const AlternatingLidar& lidar : problem.lidars) {
    digest.Add(lidar.T_base_lidar_initial.matrix().data(), sizeof(double) * 16);
  }
  digest.Add(static_cast<std::uint64_t>(options.cost.histogram.reflectance_bins));
  digest.Add(static_cast<std::uint64_t>(options.cost.histogram.intensity_bins));
  digest.Add(static_cast<std::uint64_t>(options.cost.metric));
  digest.Add(static_cast<std::uint64_t>(options.cost.histogram.binning));
  digest.Add(static_cast<std::uint64_t>(options.normalisation.reflectance));
  digest.Add(static_cast<std::uint64_t>(options.normalisation.intensity));
  digest.Add(options.normalisation.intensity_highpass_width_fraction);
  const SwatheOptions& swathe = options.cost.swathe;
  digest.Add(static_cast<std::uint64_t>(swathe.occlusion));
  digest.Add(static_cast<std::uint64_t>(swathe.occlusion_cell_px));
  digest.Add(swathe.occlusion_relative_margin);
  digest.Add(swathe.occlusion_absolute_margin_m);
  digest.Add(swathe.refresh_border_px);
  digest.Add(swathe.min_range_m);
  digest.Add(swathe.max_range_m);
  digest.Add(options.range_split_m);
  digest.Add(static_cast<std::uint64_t>(options.thin_max_points_per_cell));
  digest.Add(static_cast<std::uint64_t>(options.thin_cell_px));
  digest.Add(options.thin_margin_px);
  digest.Add(static_cast<std::uint64_t>(options.nelder_mead.max_iterations));
  digest.Add(static_cast<std::uint64_t>(alternating.lower_solver));
  digest.Add(static_cast<std::uint64_t>(alternating.lower_gradient.max_iterations));
  digest.Add(alternating.lower_gradient.function_tolerance);
  digest.Add(static_cast<std::uint64_t>(alternating.max_alternations));
  digest.Add(static_cast<std::uint64_t>(StageSpan(alternating)));
  digest.Add(static_cast<std::uint64_t>(alternating.skip_settled));
  digest.Add(alternating.settle_factor);
  digest.Add(alternating.covariance_shrink);
  digest.Add(static_cast<std::uint64_t>(alternating.penalty_frame));
  digest.Add(alternating.initial_sigma_translation_m);
  digest.Add(alternating.initial_sigma_rotation_rad);
  for (const double scale : alternating.lower_step_scale) digest.Add(scale);
  digest.Add(static_cast<std::uint64_t>(options.motion_correction));
  if (options.motion_correction) {
    const MotionCorrectionOptions& motion = options.motion;
    digest.Add(static_cast<std::uint64_t>(options.motion_correction_first_stage));
    digest.Add(static_cast<std::uint64_t>(motion.drive_scale) * 8 + static_cast<std::uint64_t>(motion.scale) * 4 +
               static_cast<std::uint64_t>(motion.turn) * 2 + static_cast<std::uint64_t>(motion.roll));
    digest.Add(motion.max_scale);
    digest.Add(motion.max_rate_rad_per_m);
    digest.Add(motion.initial_step_scale);
    digest.Add(motion.initial_step_rate_rad_per_m);
    digest.Add(static_cast<std::uint64_t>(motion.max_iterations));
  }
  return digest.hash;
}

CalibrationOutcome FinishAlternating(AlternatingSetup& setup, const AlternatingResult& solved,
                                     const CalibrationOptions& options, const AlternatingOptions& alternating) {
  CalibrationOutcome outcome;
  if (!solved.success) {
    outcome.status = CalibrationStatus::kCannotCalibrate;
    outcome.why = "alternating optimisation failed: " + solved.termination;
    return outcome;
  }
  CalibrationResult& result = outcome.result;
  const AlternatingProblem& problem = setup.problem;
  for (std::size_t l = 0; l < problem.lidars.size(); ++l) {
    LidarCalibration lidar;
    lidar.lidar = problem.lidars[l].name;
    lidar.T_base_lidar = solved.T_base_lidar[l];
    result.lidars.push_back(lidar);
  }
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    PairCost& cost = *setup.costs[p];
    const Eigen::Isometry3d& T_camera_lidar = solved.T_camera_lidar_upper[p];
    cost.SetImageBlur(0.0);
    cost.RefreshVisibility(T_camera_lidar);
    const AlternatingPair& pair = problem.pairs[p];
    PairReport report = MakePairReport(
        cost,
        problem.cameras[static_cast<std::size_t>(pair.camera)].T_camera_base() *
            problem.lidars[static_cast<std::size_t>(pair.lidar)].T_base_lidar_initial,
        setup.initial_costs[p]);
    report.final_cost = cost.Evaluate(T_camera_lidar);
    if (options.motion_correction) AppendFrameMotionCorrections(cost, report.lidar, &outcome.motion_corrections);
    outcome.pairs.push_back(report);
    result.pairs.push_back({report.camera, report.lidar, T_camera_lidar, report.final_cost});
  }
  OptimisationReport optimisation;
  optimisation.problem = "alt";
  optimisation.solver = alternating.lower_solver;
  optimisation.evaluations = solved.total_evaluations;
  optimisation.gradient_evaluations = solved.total_gradient_evaluations;
  optimisation.seconds = solved.history.empty() ? 0.0 : solved.history.back().elapsed_s;
  outcome.optimisations.push_back(optimisation);

  RecordCommonSettings(options, &result);
  result.settings["scheme"] = "alt";  // also when called with another options.scheme
  if (alternating.lower_solver == LowerSolver::kLbfgs) {
    result.settings["lower_level"] =
        "L-BFGS (analytic gradient of f, central differences of the penalty), at most " +
        std::to_string(alternating.lower_gradient.max_iterations) + " iterations, parameter scales min(" +
        NumberText(alternating.lower_gradient.initial_step_translation_m) + " m, " +
        NumberText(alternating.lower_gradient.initial_step_rotation_rad) +
        " rad x the stage's step scale; penalty sigma), function tolerance " +
        NumberText(alternating.lower_gradient.function_tolerance);
  } else {
    result.settings["lower_level"] = "Nelder-Mead, " + std::to_string(alternating.lower.max_iterations) +
                                     " iterations, initial steps min(" +
                                     NumberText(alternating.lower.initial_step_translation_m) + " m, " +
                                     NumberText(alternating.lower.initial_step_rotation_rad) +
                                     " rad x the stage's step scale; penalty sigma)";
  }
  result.settings["alternations_max"] = std::to_string(alternating.max_alternations);
  result.settings["alternation_stop"] = "both levels move, and disagree, by less than " +
                                        NumberText(alternating.stop_translation_m) + " m and " +
                                        NumberText(DegreesFromRadians(alternating.stop_rotation_rad)) + " deg";
  result.settings["alternation_schedule"] =
      alternating.skip_settled
          ? "adaptive (an alternation whose levels moved less than " + NumberText(alternating.settle_factor) +
                " x the stop thresholds, times how many times the last stage's steps its stage's are, ends its "
                "stage; in the last stage the penalty then tightens two steps)"
          : std::string("fixed (one penalty step and the stages' share per alternation, the paper)");
  result.settings["penalty_sigma0"] = NumberText(alternating.initial_sigma_translation_m) + " m, " +
                                      NumberText(alternating.initial_sigma_rotation_rad) + " rad";
  result.settings["penalty_shrink_w"] = NumberText(alternating.covariance_shrink);
  result.settings["penalty_frame"] =
      alternating.penalty_frame == PenaltyFrame::kLidar
          ? "lidar (sigmas of the lidar's position and of its turn about its own origin, carried into the "
            "camera-frame difference by the adjoint)"
          : "camera (sigmas on the camera-frame difference Log(T^ * T^-1))";
  result.settings["difference"] = "SE(3) logarithm of A * B^-1, [rho; phi]";
  result.settings["default_camera_sigma"] = NumberText(alternating.default_camera_sigma_translation_m) + " m, " +
                                            NumberText(alternating.default_camera_sigma_rotation_rad) +
                                            " rad (cameras without T_base_camera_sigma)";
  std::string stages;
  for (const OptimisationStage& s : options.stages) {
    stages += (stages.empty() ? "" : "; ") + std::string("step x") + NumberText(s.step_scale) + " blur " + NumberText(s.blur_fraction);
  }
  const int span = StageSpan(alternating);
  result.settings["stages"] =
      stages + (span < alternating.max_alternations
                    ? " (spread over the first " + std::to_string(span) + " alternations; the rest in the last stage)"
                    : std::string(" (spread over the alternations)"));
  result.settings["time_budget_s"] = NumberText(alternating.time_budget_s);
  result.termination = "alt " + std::string(MetricKindName(options.cost.metric)) + ": " + solved.termination + ", " +
                       DescribeEvaluations(alternating.lower_solver, solved.total_evaluations,
                                           solved.total_gradient_evaluations);
  result.warnings = setup.warnings;
  if (!solved.history.empty()) {
    outcome.levels_apart =
        CheckLevelsApart(alternating, solved.history.back(), solved.termination.starts_with("time budget"));
    if (outcome.levels_apart) result.warnings.push_back(DescribeLevelsApart(*outcome.levels_apart));
  }
  return outcome;
}

std::string DescribeAlternation(const AlternationRecord& record, const AlternatingProblem& problem) {
  std::ostringstream out;
  out.precision(4);
  out << "alternation " << record.alternation + 1 << ": penalty sigma " << record.sigma_translation_m << " m / "
      << DegreesFromRadians(record.sigma_rotation_rad) << " deg; costs";
  for (std::size_t p = 0; p < record.lower_cost.size(); ++p) {
    const AlternatingPair& pair = problem.pairs[p];
    out << " " << problem.cameras[static_cast<std::size_t>(pair.camera)].name << "/"
        << problem.lidars[static_cast<std::size_t>(pair.lidar)].name << " " << record.lower_cost[p];
  }
  out << "; moved " << record.max_change_translation_m * 100.0 << " cm / "
      << DegreesFromRadians(record.max_change_rotation_rad) << " deg; levels apart "
      << record.max_disagreement_translation_m * 100.0 << " cm / "
      << DegreesFromRadians(record.max_disagreement_rotation_rad) << " deg; " << record.elapsed_s << " s";
  return out.str();
}

}  // namespace scenecal
