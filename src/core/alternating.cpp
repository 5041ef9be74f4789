#include "core/alternating.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"
#include "core/upper_level.hpp"
#include "core/validation.hpp"

namespace scenecal {

bool AlternatingOptions::IsValid(std::string* why) const {
  if (max_alternations < 1) return Invalid(why, "max_alternations must be at least 1");
  if (min_alternations < 1) return Invalid(why, "min_alternations must be at least 1");
  if (stage_alternations < 0 || stage_alternations > max_alternations)
    return Invalid(why, "stage_alternations (" + std::to_string(stage_alternations) + ") must be between 0 (all) and " +
                "max_alternations (" + std::to_string(max_alternations) + ")");
  if (!(initial_sigma_translation_m > 0) || !(initial_sigma_rotation_rad > 0))
    return Invalid(why, "initial penalty sigmas must be positive");
  if (!(covariance_shrink > 0 && covariance_shrink < 1)) return Invalid(why, "covariance_shrink w must be in (0, 1)");
  if (!(stop_translation_m >= 0) || !(stop_rotation_rad >= 0)) return Invalid(why, "stop thresholds must be non-negative");
  if (!(default_camera_sigma_translation_m >= 0) || !(default_camera_sigma_rotation_rad >= 0))
    return Invalid(why, "default camera sigmas must be non-negative");
  if (!(time_budget_s >= 0)) return Invalid(why, "time budget must be non-negative");
  if (!(settle_factor >= 0)) return Invalid(why, "settle_factor must be non-negative");
  if (!(agreement_translation_m > 0) || !(agreement_rotation_rad > 0))
    return Invalid(why, "agreement thresholds must be positive");
  for (const double scale : lower_step_scale) {
    if (!(scale > 0) || !std::isfinite(scale)) return Invalid(why, "lower-level step scales must be positive numbers");
  }
  std::string lower_why;
  if (!lower.IsValid(&lower_why)) return Invalid(why, "lower level: " + lower_why);
  if (!lower_gradient.IsValid(&lower_why)) return Invalid(why, "lower level (lbfgs): " + lower_why);
  return true;
}

const char* PenaltyFrameName(PenaltyFrame frame) { return EnumName(kPenaltyFrameNames, frame); }

double AlternatingOptions::StageCoarseness(int alternation) const {
  if (lower_step_scale.empty() || !(lower_step_scale.back() > 0.0) || alternation < 0) return 1.0;
  const auto position = static_cast<std::size_t>(alternation);
  const double here = position < lower_step_scale.size() ? lower_step_scale[position] : lower_step_scale.back();
  return std::max(1.0, here / lower_step_scale.back());
}

bool AlternatingOptions::Settled(int alternation, double moved_translation_m, double moved_rotation_rad) const {
  const double factor = settle_factor * StageCoarseness(alternation);
  return moved_translation_m <= factor * stop_translation_m && moved_rotation_rad <= factor * stop_rotation_rad;
}

bool ParsePenaltyFrame(const std::string& name, PenaltyFrame* frame) {
  return ParseEnumName(kPenaltyFrameNames, name, frame);
}

Matrix6d PairPenaltyInformation(double sigma_translation_m, double sigma_rotation_rad, PenaltyFrame frame,
                                const Eigen::Isometry3d& T_camera_lidar) {
  const Matrix6d information = PenaltyInformation(sigma_translation_m, sigma_rotation_rad);
  if (frame == PenaltyFrame::kCamera) return information;
  // A camera-frame twist xi_c is the lidar-frame twist Ad(T^-1) xi_c:
  // |xi_lidar|^2_I = xi_c^T Ad(T^-1)^T I Ad(T^-1) xi_c.
  const Matrix6d to_lidar = AdjointSE3(T_camera_lidar.inverse());
  const Matrix6d mapped = to_lidar.transpose() * information * to_lidar;
  return 0.5 * (mapped + mapped.transpose());
}

bool AlternatingProblem::IsValid(std::string* why) const {
  if (cameras.empty()) return Invalid(why, "no cameras");
  if (lidars.empty()) return Invalid(why, "no lidars");
  if (pairs.empty()) return Invalid(why, "no (camera, lidar) pair with data");
  if (base_camera < 0 || base_camera >= static_cast<int>(cameras.size())) return Invalid(why, "base camera out of range");
  for (const AlternatingPair& pair : pairs) {
    if (pair.camera < 0 || pair.camera >= static_cast<int>(cameras.size()) || pair.lidar < 0 ||
        pair.lidar >= static_cast<int>(lidars.size()))
      return Invalid(why, "a pair names a camera or lidar out of range");
  }
  return true;
}

namespace {

// Central-difference steps (metres, radians) for the penalty and for costs
// without an analytic gradient: the penalty is a smooth quadratic in the
// logarithm, so truncation and rounding errors are both far below the
// gradient's size at these steps.
const Vector6d kDifferenceSteps = Vector6d::Constant(1e-6);

LowerLevelOutcome SolveLowerLevelWithGradient(const PairObjective& objective, const LowerLevelTask& task,
                                              const StopRequested& stop_requested) {
  const Eigen::Isometry3d T_lidar_camera_upper = task.T_camera_lidar_upper.inverse();
  const TransformUpdate update = task.options.transform_update;
  const Eigen::Vector3d& pivot = task.options.pivot_source;
  const auto penalty = [&](const Eigen::Isometry3d& T_camera_lidar) {
    const Vector6d difference = LogSE3(T_camera_lidar * T_lidar_camera_upper);
    return difference.dot(task.penalty_information * difference);
  };
  const CostWithGradient penalised = [&](const Eigen::Isometry3d& T_camera_lidar, Vector6d* gradient) {
    if (gradient == nullptr) return objective.cost(T_camera_lidar) + penalty(T_camera_lidar);
    Vector6d cost_gradient;
    double cost = 0.0;
    if (objective.cost_with_gradient) {
      cost = objective.cost_with_gradient(T_camera_lidar, update, pivot, &cost_gradient);
    } else {
      cost = objective.cost(T_camera_lidar);
      cost_gradient = CentralDifferenceGradient(objective.cost, T_camera_lidar, update, pivot, kDifferenceSteps);
    }
    *gradient = cost_gradient + CentralDifferenceGradient(penalty, T_camera_lidar, update, pivot, kDifferenceSteps);
    return cost + penalty(T_camera_lidar);
  };
  GradientSolverOptions options = task.gradient;
  options.transform_update = update;
  options.pivot_source = pivot;
  LowerLevelOutcome outcome;
  outcome.T_camera_lidar = task.T_camera_lidar_start;
  const GradientSolverSummary summary = MinimiseWithGradient(penalised, options, &outcome.T_camera_lidar, stop_requested);
  outcome.summary.iterations = summary.iterations;
  outcome.summary.evaluations = summary.evaluations;
  outcome.summary.initial_value = summary.initial_value;
  outcome.summary.final_value = summary.final_value;
  outcome.summary.termination = summary.start_not_finite ? NelderMeadTermination::kNonFiniteCost
                                : summary.stopped       ? NelderMeadTermination::kStopRequested
                                : summary.converged     ? NelderMeadTermination::kFunctionTolerance
                                                        : NelderMeadTermination::kMaxIterations;
  outcome.gradient_evaluations = summary.gradient_evaluations;
  outcome.objective = summary.start_not_finite ? objective.cost(outcome.T_camera_lidar) + penalty(outcome.T_camera_lidar)
                                               : summary.final_value;
  return outcome;
}

}  // namespace

LowerLevelOutcome SolveLowerLevel(const PairObjective& objective, const LowerLevelTask& task,
                                  const StopRequested& stop_requested) {
  if (objective.prepare) objective.prepare(task.T_camera_lidar_start, task.alternation);
  LowerLevelOutcome outcome;
  if (task.solver == LowerSolver::kLbfgs) {
    outcome = SolveLowerLevelWithGradient(objective, task, stop_requested);
  } else {
    const Eigen::Isometry3d T_lidar_camera_upper = task.T_camera_lidar_upper.inverse();
    const auto penalised = [&](const Eigen::Isometry3d& T_camera_lidar) {
      const Vector6d difference = LogSE3(T_camera_lidar * T_lidar_camera_upper);
      return objective.cost(T_camera_lidar) + difference.dot(task.penalty_information * difference);
    };
    outcome.T_camera_lidar = task.T_camera_lidar_start;
    outcome.summary = MinimiseOverTransform(penalised, task.options, &outcome.T_camera_lidar, stop_requested);
    outcome.objective = outcome.summary.final_value;
  }
  outcome.cost = objective.cost(outcome.T_camera_lidar);
  return outcome;
}

std::vector<LowerLevelOutcome> ThreadLowerLevelBackend::Solve(const std::vector<LowerLevelTask>& tasks,
                                                              const StopRequested& stop_requested) {
  if (before_batch_) before_batch_(tasks);
  std::vector<LowerLevelOutcome> outcomes(tasks.size());
  // One task per pair; each pair's cost parallelises over its scenes inside.
  tbb::parallel_for(std::size_t{0}, tasks.size(), [&](std::size_t i) {
    outcomes[i] = SolveLowerLevel(objectives_.at(static_cast<std::size_t>(tasks[i].pair)), tasks[i], stop_requested);
  });
  return outcomes;
}

namespace {

struct Change {
  double translation_m = 0.0;
  double rotation_rad = 0.0;
  void Include(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    translation_m = std::max(translation_m, TranslationError(a, b));
    rotation_rad = std::max(rotation_rad, RadiansFromDegrees(RotationErrorDegrees(a, b)));
  }
};

// Wall time since construction against an optional budget (0: none).
class TimeBudget {
 public:
  explicit TimeBudget(double budget_s) : budget_s_(budget_s), start_(Clock::now()) {}

  double ElapsedS() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }
  // Polled by the solvers: true once the budget has run out, and from then on.
  bool Exhausted() {
    if (budget_s_ > 0 && ElapsedS() > budget_s_) out_of_time_ = true;
    return out_of_time_;
  }
  bool RanOut() const { return out_of_time_; }

 private:
  using Clock = std::chrono::steady_clock;
  double budget_s_;
  Clock::time_point start_;
  bool out_of_time_ = false;
};

// Both levels' estimates of T_camera_lidar, per pair, between alternations.
struct LevelEstimates {
  std::vector<Eigen::Isometry3d> upper;
  std::vector<Eigen::Isometry3d> lower;
  std::vector<double> lower_cost;  // f_p at the lower estimate
};

LevelEstimates InitialEstimates(const AlternatingProblem& problem) {
  const std::size_t pair_count = problem.pairs.size();
  LevelEstimates estimates;
  estimates.upper.resize(pair_count);
  for (std::size_t p = 0; p < pair_count; ++p) {
    const AlternatingPair& pair = problem.pairs[p];
    estimates.upper[p] = problem.cameras[static_cast<std::size_t>(pair.camera)].T_camera_base() *
                         problem.lidars[static_cast<std::size_t>(pair.lidar)].T_base_lidar_initial;
  }
  estimates.lower = estimates.upper;
  estimates.lower_cost.assign(pair_count, 0.0);
  return estimates;
}

// The camera's 1-sigma of T_base_camera: the rig's, else the defaults.
Vector6d CameraSigma(const AlternatingProblem& problem, const AlternatingOptions& options, int camera) {
  const AlternatingCamera& info = problem.cameras[static_cast<std::size_t>(camera)];
  if (info.sigma) return *info.sigma;
  Vector6d sigma;
  sigma << Eigen::Vector3d::Constant(options.default_camera_sigma_translation_m),
      Eigen::Vector3d::Constant(options.default_camera_sigma_rotation_rad);
  return sigma;
}

AlternationRecord StartRecord(const AlternatingOptions& options, int alternation) {
  AlternationRecord record;
  record.alternation = alternation;
  const double shrink = std::pow(options.covariance_shrink, 0.5 * alternation);  // sigma scales by sqrt(w)
  record.sigma_translation_m = options.initial_sigma_translation_m * shrink;
  record.sigma_rotation_rad = options.initial_sigma_rotation_rad * shrink;
  return record;
}

// Per pair, at its upper estimate (the lower level's fixed target and the upper level's start).
std::vector<Matrix6d> PairInformation(const AlternatingOptions& options, const AlternationRecord& record,
                                      const std::vector<Eigen::Isometry3d>& upper) {
  std::vector<Matrix6d> information(upper.size());
  for (std::size_t p = 0; p < upper.size(); ++p) {
    information[p] = PairPenaltyInformation(record.sigma_translation_m, record.sigma_rotation_rad,
                                            options.penalty_frame, upper[p]);
  }
  return information;
}

// Lower level (eq. 13): every pair independently, from the upper estimate.
std::vector<LowerLevelTask> LowerLevelTasks(const AlternatingOptions& options, const AlternationRecord& record,
                                            const std::vector<Eigen::Isometry3d>& upper,
                                            const std::vector<Matrix6d>& information) {
  const auto alternation = static_cast<std::size_t>(record.alternation);
  const double step_scale =
      alternation < options.lower_step_scale.size() ? options.lower_step_scale[alternation] : 1.0;
  std::vector<LowerLevelTask> tasks(upper.size());
  for (std::size_t p = 0; p < upper.size(); ++p) {
    LowerLevelTask& task = tasks[p];
    task.pair = static_cast<int>(p);
    task.alternation = record.alternation;
    task.T_camera_lidar_upper = upper[p];
    task.T_camera_lidar_start = upper[p];
    task.penalty_information = information[p];
    task.options = options.lower;
    task.options.initial_step_translation_m =
        std::min(step_scale * options.lower.initial_step_translation_m, record.sigma_translation_m);
    task.options.initial_step_rotation_rad =
        std::min(step_scale * options.lower.initial_step_rotation_rad, record.sigma_rotation_rad);
    task.solver = options.lower_solver;
    task.gradient = options.lower_gradient;
    task.gradient.initial_step_translation_m =
        std::min(step_scale * options.lower_gradient.initial_step_translation_m, record.sigma_translation_m);
    task.gradient.initial_step_rotation_rad =
        std::min(step_scale * options.lower_gradient.initial_step_rotation_rad, record.sigma_rotation_rad);
  }
  return tasks;
}

void TakeLowerLevel(const std::vector<LowerLevelOutcome>& outcomes, LevelEstimates* estimates,
                    AlternationRecord* record, AlternatingResult* result, Change* change) {
  for (std::size_t p = 0; p < outcomes.size(); ++p) {
    change->Include(outcomes[p].T_camera_lidar, estimates->lower[p]);
    estimates->lower[p] = outcomes[p].T_camera_lidar;
    estimates->lower_cost[p] = outcomes[p].cost;
    record->lower_evaluations.push_back(outcomes[p].summary.evaluations);
    result->total_evaluations += outcomes[p].summary.evaluations;
    record->lower_gradient_evaluations.push_back(outcomes[p].gradient_evaluations);
    result->total_gradient_evaluations += outcomes[p].gradient_evaluations;
  }
}

// The pairs of one lidar, as the cameras of its upper-level problem.
struct LidarPairs {
  std::vector<std::size_t> members;  // indices into AlternatingProblem::pairs
  int base_member = 0;  // the reference: the base camera's pair if it sees this lidar, else the first
  int reference_camera = 0;
};

LidarPairs PairsOfLidar(const AlternatingProblem& problem, std::size_t lidar) {
  LidarPairs pairs;
  for (std::size_t p = 0; p < problem.pairs.size(); ++p) {
    if (problem.pairs[p].lidar == static_cast<int>(lidar)) pairs.members.push_back(p);
  }
  if (pairs.members.empty()) return pairs;
  for (std::size_t m = 0; m < pairs.members.size(); ++m) {
    if (problem.pairs[pairs.members[m]].camera == problem.base_camera) pairs.base_member = static_cast<int>(m);
  }
  pairs.reference_camera = problem.pairs[pairs.members[static_cast<std::size_t>(pairs.base_member)]].camera;
  return pairs;
}

UpperLevelProblem MakeUpperLevelProblem(const AlternatingProblem& problem, const AlternatingOptions& options,
                                        const LidarPairs& pairs, const LevelEstimates& estimates,
                                        const std::vector<Matrix6d>& information) {
  UpperLevelProblem upper_problem;
  upper_problem.base_camera = pairs.base_member;
  const int reference = pairs.reference_camera;
  for (const std::size_t p : pairs.members) {
    const int camera = problem.pairs[p].camera;
    UpperLevelCamera entry;
    entry.T_base_camera = problem.cameras[static_cast<std::size_t>(camera)].T_base_camera;
    // Relative uncertainty between the reference camera and this one.
    entry.sigma = (CameraSigma(problem, options, camera).array().square() +
                   (reference == problem.base_camera ? Vector6d::Zero() : CameraSigma(problem, options, reference))
                       .array()
                       .square())
                      .sqrt()
                      .matrix();
    entry.T_camera_lidar_lower = estimates.lower[p];
    entry.penalty_information = information[p];
    upper_problem.cameras.push_back(entry);
    upper_problem.T_camera_lidar_start.push_back(estimates.upper[p]);
  }
  return upper_problem;
}

// Upper level (eq. 14), per lidar, over the pairs of that lidar. False, with
// result->termination saying why, when a lidar's problem fails.
bool SolveUpperLevels(const AlternatingProblem& problem, const AlternatingOptions& options,
                      const std::vector<Matrix6d>& information, LevelEstimates* estimates, AlternationRecord* record,
                      Change* change, AlternatingResult* result) {
  record->upper_cost.assign(problem.lidars.size(), 0.0);
  for (std::size_t l = 0; l < problem.lidars.size(); ++l) {
    const LidarPairs pairs = PairsOfLidar(problem, l);
    if (pairs.members.empty()) continue;
    const UpperLevelSolution solution =
        SolveUpperLevel(MakeUpperLevelProblem(problem, options, pairs, *estimates, information));
    if (!solution.converged) {
      result->termination = "upper level failed for lidar " + problem.lidars[l].name + ": " + solution.message;
      return false;
    }
    record->upper_cost[l] = solution.final_cost;
    for (std::size_t m = 0; m < pairs.members.size(); ++m) {
      change->Include(solution.T_camera_lidar[m], estimates->upper[pairs.members[m]]);
      estimates->upper[pairs.members[m]] = solution.T_camera_lidar[m];
    }
    // T_base_lidar from the reference camera's pair, through its known transform.
    result->T_base_lidar[l] = problem.cameras[static_cast<std::size_t>(pairs.reference_camera)].T_base_camera *
                              estimates->upper[pairs.members[static_cast<std::size_t>(pairs.base_member)]];
  }
  return true;
}

// Records both levels' estimates, the change and the levels' disagreement; returns the disagreement.
Change FinishRecord(const LevelEstimates& estimates, const Change& change, AlternationRecord* record) {
  Change disagreement;
  for (std::size_t p = 0; p < estimates.upper.size(); ++p) disagreement.Include(estimates.lower[p], estimates.upper[p]);
  record->T_camera_lidar_lower = estimates.lower;
  record->T_camera_lidar_upper = estimates.upper;
  record->lower_cost = estimates.lower_cost;
  record->max_change_translation_m = change.translation_m;
  record->max_change_rotation_rad = change.rotation_rad;
  record->max_disagreement_translation_m = disagreement.translation_m;
  record->max_disagreement_rotation_rad = disagreement.rotation_rad;
  return disagreement;
}

// Why the alternations stop after `alternation`; empty to go on.
std::string StopReason(const AlternatingOptions& options, int alternation, int run, bool out_of_time,
                       const Change& change, const Change& disagreement) {
  if (out_of_time) {
    std::ostringstream message;
    message << "time budget of " << options.time_budget_s << " s ran out during alternation " << alternation + 1
            << "; the best estimate so far is returned";
    return message.str();
  }
  const bool settled = change.translation_m <= options.stop_translation_m &&
                       change.rotation_rad <= options.stop_rotation_rad &&
                       disagreement.translation_m <= options.stop_translation_m &&
                       disagreement.rotation_rad <= options.stop_rotation_rad;
  if (alternation > 0 && alternation + 1 >= options.min_alternations && settled) {
    return "converged after " + std::to_string(run) + " alternations" +
           (run != alternation + 1 ? " (schedule position " + std::to_string(alternation + 1) + ")" : std::string()) +
           ": both levels moved and disagree less than the stop thresholds";
  }
  return "";
}

// The schedule position after `alternation`: the next one, or with skip_settled
// and levels that barely moved, the next stage's first (the last stage: two on).
int NextAlternation(const AlternatingOptions& options, int alternation, const Change& change) {
  const bool settled = options.Settled(alternation, change.translation_m, change.rotation_rad);
  if (!options.skip_settled || !settled || alternation == 0) return alternation + 1;
  for (const int start : options.stage_starts) {
    if (start > alternation) return start;
  }
  return alternation + 2;
}

}  // namespace

AlternatingResult SolveAlternating(const AlternatingProblem& problem, const AlternatingOptions& options,
                                   LowerLevelBackend& backend, const AlternatingProgress& progress) {
  AlternatingResult result;
  std::string why;
  if (!problem.IsValid(&why) || !options.IsValid(&why)) {
    result.termination = "invalid problem: " + why;
    return result;
  }
  TimeBudget budget(options.time_budget_s);
  const StopRequested stop_requested = [&budget] { return budget.Exhausted(); };

  const std::size_t pair_count = problem.pairs.size();
  LevelEstimates estimates = InitialEstimates(problem);
  result.T_base_lidar.resize(problem.lidars.size());
  for (std::size_t l = 0; l < problem.lidars.size(); ++l)
    result.T_base_lidar[l] = problem.lidars[l].T_base_lidar_initial;

  int run = 0;  // alternations run; `alternation` is the schedule's position (penalty, stage)
  for (int alternation = 0; alternation < options.max_alternations;) {
    ThrowIfInterrupted();
    AlternationRecord record = StartRecord(options, alternation);
    const std::vector<Matrix6d> information = PairInformation(options, record, estimates.upper);
    const std::vector<LowerLevelTask> tasks = LowerLevelTasks(options, record, estimates.upper, information);
    const std::vector<LowerLevelOutcome> outcomes = backend.Solve(tasks, stop_requested);
    if (outcomes.size() != pair_count) {
      result.termination = "lower-level backend returned " + std::to_string(outcomes.size()) + " outcomes for " +
                           std::to_string(pair_count) + " pairs";
      return result;
    }
    Change change;
    TakeLowerLevel(outcomes, &estimates, &record, &result, &change);
    if (!SolveUpperLevels(problem, options, information, &estimates, &record, &change, &result)) return result;

    const Change disagreement = FinishRecord(estimates, change, &record);
    record.elapsed_s = budget.ElapsedS();
    result.history.push_back(record);
    result.alternations = ++run;
    if (progress) progress(record);
    result.termination = StopReason(options, alternation, run, budget.RanOut(), change, disagreement);
    if (!result.termination.empty()) break;
    alternation = NextAlternation(options, alternation, change);
  }
  if (result.termination.empty()) {
    result.termination = "reached the maximum of " + std::to_string(options.max_alternations) + " alternations" +
                         (run != options.max_alternations
                              ? " (schedule positions; " + std::to_string(run) + " run, the settled ones skipped)"
                              : std::string());
  }
  result.T_camera_lidar_upper = estimates.upper;
  result.T_camera_lidar_lower = estimates.lower;
  result.pair_cost = estimates.lower_cost;
  result.success = true;
  return result;
}

}  // namespace scenecal
