#include "core/calibrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include <fmt/format.h>

#include "core/interrupt.hpp"
#include "core/number_text.hpp"

namespace scenecal {

namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

std::string VectorText(const Eigen::Vector3d& v) {
  return "[" + NumberText(v.x()) + ", " + NumberText(v.y()) + ", " + NumberText(v.z()) + "]";
}

std::string StagesBrief(const std::vector<NelderMeadSummary>& stages) {
  int evaluations = 0, iterations = 0;
  for (const auto& s : stages) {
    evaluations += s.evaluations;
    iterations += s.iterations;
  }
  std::ostringstream out;
  out << stages.size() << " runs, " << iterations << " iterations, " << evaluations << " evaluations";
  if (!stages.empty()) out << ", last: " << NelderMeadTerminationName(stages.back().termination);
  return out.str();
}

std::string GradientRunsBrief(const std::vector<GradientSolverSummary>& runs) {
  int evaluations = 0, gradient_evaluations = 0, iterations = 0;
  for (const auto& r : runs) {
    evaluations += r.evaluations;
    gradient_evaluations += r.gradient_evaluations;
    iterations += r.iterations;
  }
  std::ostringstream out;
  out << runs.size() << " lbfgs runs, " << iterations << " iterations, "
      << DescribeEvaluations(LowerSolver::kLbfgs, evaluations, gradient_evaluations);
  if (!runs.empty()) out << ", last: " << (runs.back().converged ? "converged" : "not converged");
  return out.str();
}

// The settings of the once and joint schemes beyond the common ones.
void RecordOnceOrJointSettings(const CalibrationOptions& options, CalibrationResult* result) {
  RecordCommonSettings(options, result);
  std::map<std::string, std::string>& settings = result->settings;
  settings["rotation_pivot"] = options.pivot_at_observed_centroid ? "observed centroid" : "lidar origin";
  const bool lbfgs = options.lower_solver == LowerSolver::kLbfgs;
  settings["max_iterations_per_run"] =
      std::to_string(lbfgs ? options.gradient.max_iterations : options.nelder_mead.max_iterations);
  std::string stages;
  for (const OptimisationStage& s : options.stages) {
    stages += (stages.empty() ? "" : "; ") + std::string("step x") + NumberText(s.step_scale) + " blur " +
              NumberText(s.blur_fraction) + " restarts " + std::to_string(s.restarts);
  }
  settings["stages"] = stages;
  // Simplex: the initial simplex edges; lbfgs: the parameter scales (first stage).
  settings["initial_step_m"] = NumberText(lbfgs ? options.gradient.initial_step_translation_m
                                                : options.nelder_mead.initial_step_translation_m);
  settings["initial_step_rad"] = NumberText(lbfgs ? options.gradient.initial_step_rotation_rad
                                                  : options.nelder_mead.initial_step_rotation_rad);
  settings["time_budget_s"] = NumberText(options.time_budget_s);
}

// once: the largest pairwise difference of the pairs' implied T_base_lidar,
// recorded, and a warning beyond the agreement thresholds.
void RecordOnceAgreement(const CalibrationOptions& options, const std::string& lidar,
                         const std::vector<Eigen::Isometry3d>& implied_base_lidar, CalibrationResult* result,
                         const std::function<void(const std::string&)>& say) {
  double spread_m = 0.0, spread_deg = 0.0;
  for (std::size_t a = 0; a < implied_base_lidar.size(); ++a) {
    for (std::size_t b = a + 1; b < implied_base_lidar.size(); ++b) {
      spread_m = std::max(spread_m, TranslationError(implied_base_lidar[a], implied_base_lidar[b]));
      spread_deg = std::max(spread_deg, RotationErrorDegrees(implied_base_lidar[a], implied_base_lidar[b]));
    }
  }
  result->settings["once_agreement_" + lidar + "_translation_m"] = NumberText(spread_m);
  result->settings["once_agreement_" + lidar + "_rotation_deg"] = NumberText(spread_deg);
  say("once " + lidar + ": pairs' T_base_lidar agree within " + NumberText(spread_m) + " m, " +
      NumberText(spread_deg) + " deg");
  if (spread_m > options.agreement_warning_translation_m || spread_deg > options.agreement_warning_rotation_deg) {
    result->warnings.push_back("lidar " + lidar + ": the pairs' T_base_lidar disagree by " + NumberText(spread_m) +
                               " m and " + NumberText(spread_deg) + " deg; T_base_lidar is their mean");
  }
}

}  // namespace

Calibrator::Calibrator(const CalibrationInput& input, const CalibrationOptions& options, ProgressCallback progress)
    : input_(input), options_(options), progress_(std::move(progress)) {
  std::string why;
  if (!options_.IsValid(&why)) {
    Cannot(CalibrationStatus::kInvalidOptions, "invalid options: " + why);
    return;
  }
  alternating_options_ = AlternatingOptionsFor(options_);
  if (options_.scheme == CalibrationScheme::kAlt && !alternating_options_.IsValid(&why)) {
    Cannot(CalibrationStatus::kInvalidOptions, "invalid options: " + why);
    return;
  }
  if (input_.rig.cameras.empty() || input_.rig.lidars.empty()) {
    Cannot(CalibrationStatus::kCannotCalibrate, "the rig needs at least one camera and one lidar");
    return;
  }
  if (options_.threads > 0) {
    thread_limit_.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(options_.threads));
  }
  const auto start = Clock::now();
  BuildPairs();
  if (status_ != CalibrationStatus::kSuccess) return;
  BuildAlternatingSetup();
  build_s_ = SecondsSince(start);
}

Calibrator::~Calibrator() = default;

CalibrationStatus Calibrator::Cannot(CalibrationStatus status, std::string why) {
  status_ = status;
  why_ = std::move(why);
  return status_;
}

void Calibrator::Say(const std::string& message) const {
  if (progress_) progress_(message);
}

void Calibrator::BuildPairs() {
  PreparedImageCache images;  // a camera frame's images, once for every lidar's pair
  for (const LidarInfo& lidar : input_.rig.lidars) {
    LidarPairs built;
    built.lidar = &lidar;
    int scenes = 0;
    for (const CameraInfo& camera : input_.rig.cameras) {
      built.pairs.push_back(std::make_unique<PairCost>(BuildPairCost(input_, camera, lidar.name, options_, &images)));
      scenes += built.pairs.back()->SceneCount();
    }
    if (scenes == 0) {
      Cannot(CalibrationStatus::kCannotCalibrate,
             "lidar " + lidar.name +
                 ": no scene: no camera frame has scans of this lidar within its swathe window, or the images, "
                 "scans and trajectory do not overlap in time");
      return;
    }
    int used = 0;
    for (auto& pair : built.pairs) {
      used += pair->RefreshVisibility(pair->Camera().T_camera_base() * lidar.T_base_lidar);
    }
    if (used == 0) {
      Cannot(CalibrationStatus::kCannotCalibrate,
             DescribeUnusable(lidar.name, built.pairs, options_.cost.min_points_per_scene));
      return;
    }
    if (InformativeChoiceStage(options_) == 0) {
      for (auto& pair : built.pairs) KeepInformativeFrames(*pair, pair->Camera().T_camera_base() * lidar.T_base_lidar);
    }
    // Initial costs (visibility at the initial guess).
    for (const auto& pair : built.pairs) {
      built.initial_costs.push_back(pair->Evaluate(pair->Camera().T_camera_base() * lidar.T_base_lidar));
    }
    lidars_.push_back(std::move(built));
  }
}

bool Calibrator::ChoosesInformativeBefore(int stage_index) const {
  return stage_index != 0 && stage_index == InformativeChoiceStage(options_);  // 0: chosen at construction
}

void Calibrator::KeepInformativeFrames(PairCost& pair, const Eigen::Isometry3d& T_camera_lidar) {
  if (pair.SceneCount() == 0) return;
  const int pool = pair.FrameCount();
  // Judged on the sharp images with the visibility at T_camera_lidar, as at the initial guess: a blurred
  // stage's image has lost the edges that the information counts.
  pair.SetImageBlur(0.0);
  pair.RefreshVisibility(T_camera_lidar);
  InformativeChoiceOptions choice_options;
  choice_options.max_variance_ratio = options_.scenes.auto_variance_ratio;
  choice_options.min_count = static_cast<std::size_t>(options_.scenes.min_auto_scenes);
  const InformativeChoice choice =
      pair.KeepMostInformative(T_camera_lidar, options_.scenes.scenes_per_camera, choice_options);
  pair.RefreshVisibility(T_camera_lidar);
  Say("scenes " + pair.Camera().name + "/" + pair.Lidar() + ": kept the " + std::to_string(pair.FrameCount()) +
      " most informative of " + std::to_string(pool) + " frames (predicted variance " +
      NumberText(choice.predicted_variance_chosen / choice.predicted_variance_pool) + " times the whole pool's)");
}

void Calibrator::BuildAlternatingSetup() {
  AlternatingProblem& problem = alternating_.problem;
  const Rig& rig = input_.rig;
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    const CameraInfo& camera = rig.cameras[c];
    problem.cameras.push_back({camera.name, camera.T_base_camera, camera.T_base_camera_sigma});
    if (camera.name == rig.base_frame) problem.base_camera = static_cast<int>(c);
  }
  for (std::size_t l = 0; l < lidars_.size(); ++l) {
    const LidarPairs& built = lidars_[l];
    problem.lidars.push_back({built.lidar->name, built.lidar->T_base_lidar});
    for (std::size_t c = 0; c < built.pairs.size(); ++c) {
      PairCost& cost = *built.pairs[c];
      if (cost.UsedSceneCount() == 0) {
        if (cost.SceneCount() > 0) {
          alternating_.warnings.push_back("pair " + cost.Camera().name + "/" + built.lidar->name +
                                          ": no usable scene at the initial guess; pair left out");
        }
        continue;
      }
      alternating_.initial_costs.push_back(built.initial_costs[c]);
      problem.pairs.push_back({static_cast<int>(c), static_cast<int>(l)});
      alternating_.costs.push_back(&cost);
    }
  }
}

std::vector<PairObjective> Calibrator::AlternatingObjectives() {
  return alternating_.Objectives(options_, alternating_options_);
}

LowerLevelBatchHook Calibrator::AlternatingBatchHook(const ProgressCallback& progress) {
  return alternating_.BatchHook(options_, alternating_options_, progress);
}

std::uint64_t Calibrator::AlternatingFingerprint() const {
  return alternating_.Fingerprint(options_, alternating_options_);
}

CalibrationOutcome Calibrator::Solve(const LowerLevelBackendFactory& lower_levels) {
  if (status_ != CalibrationStatus::kSuccess) {
    CalibrationOutcome failed;
    failed.status = status_;
    failed.why = why_;
    return failed;
  }
  if (options_.scheme == CalibrationScheme::kAlt) return SolveAlternating(lower_levels);
  return SolveOnceOrJoint();
}

CalibrationOutcome Calibrator::SolveAlternating(const LowerLevelBackendFactory& lower_levels) {
  const auto start = Clock::now();
  Say("built " + std::to_string(alternating_.costs.size()) + " pair cost(s) in " + NumberText(build_s_) + " s");
  std::vector<PairObjective> objectives = AlternatingObjectives();
  LowerLevelBatchHook hook = AlternatingBatchHook(progress_);
  std::unique_ptr<LowerLevelBackend> backend =
      lower_levels ? lower_levels(std::move(objectives), std::move(hook))
                   : std::make_unique<ThreadLowerLevelBackend>(std::move(objectives), std::move(hook));
  const AlternatingResult solved =
      scenecal::SolveAlternating(alternating_.problem, alternating_options_, *backend,
                                 [&](const AlternationRecord& record) {
                                   Say(DescribeAlternation(record, alternating_.problem));
                                 });
  CalibrationOutcome outcome = FinishAlternating(alternating_, solved, options_, alternating_options_);
  outcome.result.timings_s["build_swathes"] = build_s_;
  outcome.result.timings_s["optimise"] = solved.history.empty() ? 0.0 : solved.history.back().elapsed_s;
  outcome.result.timings_s["total"] = build_s_ + SecondsSince(start);
  outcome.alternating = AlternatingHistory{alternating_.problem, solved};
  return outcome;
}

void Calibrator::Optimise(const std::string& name, double initial_cost, const NelderMeadOptions& nelder_mead,
                          const std::function<double(const Eigen::Isometry3d&)>& cost,
                          const CostWithGradient& cost_with_gradient, const StagePreparation& prepare,
                          Eigen::Isometry3d* transform, OnceOrJointRun* run) {
  const CalibrationOptions& options = options_;
  const auto problem_start = Clock::now();
  OptimisationReport report;
  report.problem = name;
  Say(report.problem + ": start (" + LowerSolverName(options.lower_solver) + "), cost " + NumberText(initial_cost) +
      ", rotation pivot (lidar frame, m) " + VectorText(nelder_mead.pivot_source));
  MinimiseWithLowerSolver(options, options.stages, nelder_mead, cost, cost_with_gradient, prepare, transform, &report,
                          run->stop_requested);
  std::string brief;
  double final_value = std::numeric_limits<double>::quiet_NaN();
  if (options.lower_solver == LowerSolver::kLbfgs) {
    if (!report.gradient_runs.empty()) final_value = report.gradient_runs.back().final_value;
    brief = GradientRunsBrief(report.gradient_runs);
    for (std::size_t r = 0; r < report.gradient_runs.size(); ++r)
      Say(report.problem + ": run " + std::to_string(r + 1) + ": " + report.gradient_runs[r].BriefReport());
  } else {
    if (!report.stages.empty()) final_value = report.stages.back().final_value;
    brief = StagesBrief(report.stages);
  }
  report.seconds = SecondsSince(problem_start);
  Say(report.problem + ": " + brief + ", cost " +
      (std::isnan(final_value) ? std::string("-") : NumberText(final_value)) + ", " + NumberText(report.seconds) +
      " s");
  run->terminations.push_back(report.problem + ": " + brief);
  run->outcome.optimisations.push_back(report);
}

void Calibrator::CorrectMotionBeforeStage(const std::vector<PairCost*>& pairs, const OptimisationStage& stage,
                                          const std::vector<Eigen::Isometry3d>& T_camera_lidar_now,
                                          const std::string& lidar) {
  if (!options_.motion_correction) return;
  // prepare is called with the elements of options.stages (MinimiseWithLowerSolver).
  const auto in_schedule = std::find_if(options_.stages.begin(), options_.stages.end(),
                                        [&](const OptimisationStage& s) { return &s == &stage; });
  if (in_schedule - options_.stages.begin() < options_.motion_correction_first_stage) return;
  const MotionCorrectionSummary summary = EstimateMotionCorrections(pairs, T_camera_lidar_now, options_.motion);
  // The visibility follows the re-posed scans.
  for (std::size_t p = 0; p < pairs.size(); ++p) pairs[p]->RefreshVisibility(T_camera_lidar_now[p]);
  std::string names;
  for (const PairCost* pair : pairs) names += (names.empty() ? "" : ", ") + pair->Camera().name + "/" + lidar;
  Say("motion correction (" + names + "): " + DescribeMotionCorrection(summary));
}

void Calibrator::SolveJoint(LidarPairs& problem, std::vector<Eigen::Isometry3d>* T_camera_lidar,
                            std::vector<bool>* solved, OnceOrJointRun* run) {
  const LidarInfo& lidar = *problem.lidar;
  std::vector<const PairCost*> pairs;
  for (const auto& pair : problem.pairs) pairs.push_back(pair.get());
  Eigen::Isometry3d T_base_lidar = lidar.T_base_lidar;
  NelderMeadOptions nelder_mead = options_.nelder_mead;
  if (options_.pivot_at_observed_centroid) {
    nelder_mead.pivot_source = ObservedCentroid(pairs, T_base_lidar).value_or(nelder_mead.pivot_source);
  }
  Optimise(
      "joint " + lidar.name, EvaluateJoint(pairs, T_base_lidar), nelder_mead,
      [&](const Eigen::Isometry3d& T) { return EvaluateJoint(pairs, T); },
      [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
        return EvaluateJointWithGradient(pairs, T, nelder_mead.transform_update, nelder_mead.pivot_source, gradient);
      },
      [&, stage_index = 0](const OptimisationStage& stage, const Eigen::Isometry3d& T) mutable {
        if (ChoosesInformativeBefore(stage_index++)) {
          for (auto& pair : problem.pairs) KeepInformativeFrames(*pair, pair->Camera().T_camera_base() * T);
        }
        std::vector<PairCost*> stage_pairs;
        std::vector<Eigen::Isometry3d> stage_T_camera_lidar;
        for (auto& pair : problem.pairs) {
          stage_pairs.push_back(pair.get());
          stage_T_camera_lidar.push_back(pair->Camera().T_camera_base() * T);
          PreparePairForStage(*pair, stage, stage_T_camera_lidar.back());
        }
        CorrectMotionBeforeStage(stage_pairs, stage, stage_T_camera_lidar, lidar.name);
      },
      &T_base_lidar, run);
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    (*T_camera_lidar)[p] = problem.pairs[p]->Camera().T_camera_base() * T_base_lidar;
    (*solved)[p] = true;
  }
}

void Calibrator::SolveEachPair(LidarPairs& problem, std::vector<Eigen::Isometry3d>* T_camera_lidar,
                               std::vector<bool>* solved, OnceOrJointRun* run) {
  const LidarInfo& lidar = *problem.lidar;
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    PairCost& pair = *problem.pairs[p];
    (*T_camera_lidar)[p] = pair.Camera().T_camera_base() * lidar.T_base_lidar;
    if (pair.UsedSceneCount() == 0) {
      run->outcome.result.warnings.push_back("pair " + pair.Camera().name + "/" + lidar.name +
                                             ": no usable scene at the initial guess; pair left out");
      continue;
    }
    NelderMeadOptions nelder_mead = options_.nelder_mead;
    if (options_.pivot_at_observed_centroid) {
      nelder_mead.pivot_source = ObservedCentroid({&pair}, lidar.T_base_lidar).value_or(nelder_mead.pivot_source);
    }
    Optimise(
        "once " + pair.Camera().name + "/" + lidar.name, problem.initial_costs[p], nelder_mead,
        [&](const Eigen::Isometry3d& T) { return pair.Evaluate(T); },
        [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
          if (gradient == nullptr) return pair.Evaluate(T);
          return pair.EvaluateWithGradient(T, nelder_mead.transform_update, nelder_mead.pivot_source, gradient);
        },
        [&, stage_index = 0](const OptimisationStage& stage, const Eigen::Isometry3d& T) mutable {
          if (ChoosesInformativeBefore(stage_index++)) KeepInformativeFrames(pair, T);
          PreparePairForStage(pair, stage, T);
          CorrectMotionBeforeStage({&pair}, stage, {T}, lidar.name);
        },
        &(*T_camera_lidar)[p], run);
    (*solved)[p] = true;
  }
}

bool Calibrator::FinishLidar(LidarPairs& problem, const std::vector<Eigen::Isometry3d>& T_camera_lidar,
                             const std::vector<bool>& solved, OnceOrJointRun* run) {
  const LidarInfo& lidar = *problem.lidar;
  CalibrationOutcome& outcome = run->outcome;
  // Final costs with visibility refreshed at the answer; per-pair results.
  std::vector<Eigen::Isometry3d> implied_base_lidar;
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    PairCost& pair = *problem.pairs[p];
    const Eigen::Isometry3d T_initial = pair.Camera().T_camera_base() * lidar.T_base_lidar;
    if (!solved[p]) {
      outcome.pairs.push_back(MakePairReport(pair, T_initial, problem.initial_costs[p]));
      continue;
    }
    pair.SetImageBlur(0.0);
    pair.RefreshVisibility(T_camera_lidar[p]);
    if (options_.motion_correction) AppendFrameMotionCorrections(pair, lidar.name, &outcome.motion_corrections);
    PairReport report = MakePairReport(pair, T_initial, problem.initial_costs[p]);
    report.final_cost = pair.Evaluate(T_camera_lidar[p]);
    outcome.pairs.push_back(report);
    outcome.result.pairs.push_back({pair.Camera().name, lidar.name, T_camera_lidar[p], report.final_cost});
    implied_base_lidar.push_back(pair.Camera().T_base_camera * T_camera_lidar[p]);
  }
  if (implied_base_lidar.empty()) {
    outcome.status = CalibrationStatus::kCannotCalibrate;
    outcome.why = DescribeUnusable(lidar.name, problem.pairs, options_.cost.min_points_per_scene);
    return false;
  }
  LidarCalibration lidar_result;
  lidar_result.lidar = lidar.name;
  lidar_result.T_base_lidar = MeanTransform(implied_base_lidar);
  outcome.result.lidars.push_back(lidar_result);
  if (options_.scheme == CalibrationScheme::kOnce && implied_base_lidar.size() > 1) {
    RecordOnceAgreement(options_, lidar.name, implied_base_lidar, &outcome.result,
                        [this](const std::string& message) { Say(message); });
  }
  return true;
}

CalibrationOutcome Calibrator::SolveOnceOrJoint() {
  const auto start = Clock::now();
  const Clock::time_point deadline =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.time_budget_s));
  OnceOrJointRun run;
  run.stop_requested = [&] { return options_.time_budget_s > 0.0 && Clock::now() > deadline; };
  CalibrationResult& result = run.outcome.result;
  RecordOnceOrJointSettings(options_, &result);
  result.timings_s["build_swathes"] = build_s_;
  Say("built " + std::to_string(lidars_.size()) + " lidar problem(s) in " + NumberText(build_s_) + " s");

  for (LidarPairs& problem : lidars_) {
    std::vector<Eigen::Isometry3d> T_camera_lidar(problem.pairs.size());
    std::vector<bool> solved(problem.pairs.size(), false);
    if (options_.scheme == CalibrationScheme::kJoint) {
      SolveJoint(problem, &T_camera_lidar, &solved, &run);
    } else {
      SolveEachPair(problem, &T_camera_lidar, &solved, &run);
    }
    if (!FinishLidar(problem, T_camera_lidar, solved, &run)) return run.outcome;
  }
  result.timings_s["optimise"] = SecondsSince(start);
  result.timings_s["total"] = build_s_ + SecondsSince(start);
  std::string termination = CalibrationSchemeName(options_.scheme) + std::string(" ") +
                            MetricKindName(options_.cost.metric) + ": ";
  for (std::size_t i = 0; i < run.terminations.size(); ++i) termination += (i ? "; " : "") + run.terminations[i];
  if (run.stop_requested()) termination += " (time budget reached)";
  result.termination = termination;
  return run.outcome;
}

Calibrator::LidarPairs* Calibrator::FindLidar(const std::string& lidar) {
  for (LidarPairs& built : lidars_) {
    if (built.lidar->name == lidar) return &built;
  }
  return nullptr;
}

std::vector<PairCost*> Calibrator::PairsAt(const std::string& lidar, const Eigen::Isometry3d& T_base_lidar,
                                           Binning binning, const std::string& only_camera) {
  std::vector<PairCost*> pairs;
  LidarPairs* built = FindLidar(lidar);
  if (built == nullptr) return pairs;
  for (auto& pair : built->pairs) {
    if (pair->SceneCount() == 0 || (!only_camera.empty() && pair->Camera().name != only_camera)) continue;
    pair->SetBinning(binning);
    pair->SetImageBlur(0.0);
    pair->RefreshVisibility(pair->Camera().T_camera_base() * T_base_lidar);
    pairs.push_back(pair.get());
  }
  CorrectMotionAtAnswer(options_, pairs, T_base_lidar);
  return pairs;
}

PairCost* Calibrator::PairAt(const std::string& camera, const std::string& lidar,
                             const Eigen::Isometry3d& T_base_lidar) {
  // That pair alone: preparing every pair of the lidar for each one would repeat the work per camera.
  const std::vector<PairCost*> pairs = PairsAt(lidar, T_base_lidar, options_.cost.histogram.binning, camera);
  return pairs.empty() ? nullptr : pairs.front();
}

std::vector<LidarUncertainty> Calibrator::EstimateUncertainty(const CalibrationResult& result,
                                                              const UncertaintyOptions& uncertainty_options,
                                                              const std::vector<LidarBasinCheck>& basin_checks) {
  std::vector<LidarUncertainty> estimates;
  for (const LidarCalibration& lidar : result.lidars) {
    UncertaintyOptions options = uncertainty_options;
    const bool basin_checked = std::any_of(basin_checks.begin(), basin_checks.end(), [&](const LidarBasinCheck& c) {
      return c.lidar == lidar.lidar && c.checked;
    });
    if (basin_checked) options.search_past_rise = false;
    // On the smooth cost of the same swathes: the hard one is piecewise constant.
    const std::vector<PairCost*> pairs = PairsAt(lidar.lidar, lidar.T_base_lidar, Binning::kBSpline);
    const std::vector<const PairCost*> views(pairs.begin(), pairs.end());
    estimates.push_back(EstimateLidarUncertainty(views, lidar.T_base_lidar, options));
    for (PairCost* pair : pairs) pair->SetBinning(options_.cost.histogram.binning);
  }
  return estimates;
}

DriftTestResult Calibrator::TestDriftAt(const CalibrationResult& result, const DriftTestOptions& test_options) {
  std::vector<PairCost*> pairs;
  std::vector<Eigen::Isometry3d> T_camera_lidar;
  for (const LidarCalibration& lidar : result.lidars) {
    for (PairCost* pair : PairsAt(lidar.lidar, lidar.T_base_lidar, options_.cost.histogram.binning)) {
      pairs.push_back(pair);
      T_camera_lidar.push_back(pair->Camera().T_camera_base() * lidar.T_base_lidar);
    }
  }
  return TestDrift(pairs, T_camera_lidar, test_options);
}

std::vector<LidarBasinCheck> Calibrator::CheckBasins(const CalibrationResult& result,
                                                     const BasinCheckOptions& check_options) {
  std::vector<LidarBasinCheck> checks;
  for (const LidarCalibration& answer : result.lidars) {
    const std::vector<PairCost*> pairs = PairsAt(answer.lidar, answer.T_base_lidar, options_.cost.histogram.binning);
    checks.push_back(CheckLidarBasin(pairs, answer, options_, check_options, progress_));
  }
  return checks;
}

std::vector<std::string> Calibrator::AdoptBetterRestarts(const BasinCheckOptions& check_options,
                                                         CalibrationResult* result,
                                                         std::vector<LidarBasinCheck>* checks) {
  std::vector<std::string> adopted;
  const bool cameras_uncertain = std::any_of(input_.rig.cameras.begin(), input_.rig.cameras.end(),
                                             [](const CameraInfo& camera) { return camera.T_base_camera_sigma; });
  if (options_.scheme == CalibrationScheme::kAlt && cameras_uncertain) return adopted;
  for (LidarBasinCheck& check : *checks) {
    const int better = BetterRestart(check, check_options);
    if (better < 0) continue;
    const auto answer = std::find_if(result->lidars.begin(), result->lidars.end(),
                                     [&](const LidarCalibration& lidar) { return lidar.lidar == check.lidar; });
    if (answer == result->lidars.end()) continue;
    AdoptRestart(better, check_options, &check, &answer->T_base_lidar);
    for (PairCost* pair : PairsAt(check.lidar, answer->T_base_lidar, options_.cost.histogram.binning)) {
      for (PairCalibration& pair_result : result->pairs) {
        if (pair_result.lidar != check.lidar || pair_result.camera != pair->Camera().name) continue;
        pair_result.T_camera_lidar = pair->Camera().T_camera_base() * answer->T_base_lidar;
        pair_result.cost = pair->Evaluate(pair_result.T_camera_lidar);
      }
    }
    Say(fmt::format("basin check {}: the restart from {:+.2f} deg about base {} ended at a lower cost ({:.6f} against "
                    "{:.6f}), {:.2f} cm and {:.3f} deg from the calibration's answer: it is the answer now",
                    check.lidar, check.restarts[better].sign * DegreesFromRadians(check_options.offset_rad),
                    "xyz"[check.restarts[better].axis], check.cost_answer, check.cost_calibrated,
                    100.0 * check.calibrated_translation_apart_m,
                    DegreesFromRadians(check.calibrated_rotation_apart_rad)));
    adopted.push_back(check.lidar);
  }
  return adopted;
}

CalibrationOutcome Calibrate(const CalibrationInput& input, const CalibrationOptions& options,
                             const ProgressCallback& progress) {
  Calibrator calibrator(input, options, progress);
  return calibrator.Solve();
}

}  // namespace scenecal
