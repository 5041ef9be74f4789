#include "core/alternating.hpp"

#include <algorithm>
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

}  // namespace

AlternatingResult SolveAlternating(const AlternatingProblem& problem, const AlternatingOptions& options,
                                   LowerLevelBackend& backend, const AlternatingProgress& progress) {
  AlternatingResult result;
  std::string why;
  if (!problem.IsValid(&why) || !options.IsValid(&why)) {
    result.termination = "invalid problem: " + why;
    return result;
  }
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start_time = Clock::now();
  const auto elapsed_s = [&] { return std::chrono::duration<double>(Clock::now() - start_time).count(); };
  bool out_of_time = false;
  const StopRequested stop_requested = [&] {
    if (options.time_budget_s > 0 && elapsed_s() > options.time_budget_s) out_of_time = true;
    return out_of_time;
  };

  const std::size_t pair_count = problem.pairs.size();
  std::vector<Eigen::Isometry3d> upper(pair_count);
  for (std::size_t p = 0; p < pair_count; ++p) {
    const AlternatingPair& pair = problem.pairs[p];
    upper[p] = problem.cameras[static_cast<std::size_t>(pair.camera)].T_camera_base() *
               problem.lidars[static_cast<std::size_t>(pair.lidar)].T_base_lidar_initial;
  }
  std::vector<Eigen::Isometry3d> lower = upper;
  std::vector<double> lower_cost(pair_count, 0.0);
  result.T_base_lidar.resize(problem.lidars.size());
  for (std::size_t l = 0; l < problem.lidars.size(); ++l) result.T_base_lidar[l] = problem.lidars[l].T_base_lidar_initial;

  const auto camera_sigma = [&](int camera) -> Vector6d {
    const AlternatingCamera& info = problem.cameras[static_cast<std::size_t>(camera)];
    if (info.sigma) return *info.sigma;
    Vector6d sigma;
    sigma << Eigen::Vector3d::Constant(options.default_camera_sigma_translation_m),
        Eigen::Vector3d::Constant(options.default_camera_sigma_rotation_rad);
    return sigma;
  };

  for (int alternation = 0; alternation < options.max_alternations; ++alternation) {
    ThrowIfInterrupted();
    AlternationRecord record;
    record.alternation = alternation;
    const double shrink = std::pow(options.covariance_shrink, 0.5 * alternation);  // sigma scales by sqrt(w)
    record.sigma_translation_m = options.initial_sigma_translation_m * shrink;
    record.sigma_rotation_rad = options.initial_sigma_rotation_rad * shrink;
    // Per pair, at its upper estimate (the lower level's fixed target and the upper level's start).
    std::vector<Matrix6d> information(pair_count);
    for (std::size_t p = 0; p < pair_count; ++p) {
      information[p] = PairPenaltyInformation(record.sigma_translation_m, record.sigma_rotation_rad,
                                              options.penalty_frame, upper[p]);
    }

    const double step_scale = static_cast<std::size_t>(alternation) < options.lower_step_scale.size()
                                  ? options.lower_step_scale[static_cast<std::size_t>(alternation)]
                                  : 1.0;
    // Lower level (eq. 13): every pair independently, from the upper estimate.
    std::vector<LowerLevelTask> tasks(pair_count);
    for (std::size_t p = 0; p < pair_count; ++p) {
      LowerLevelTask& task = tasks[p];
      task.pair = static_cast<int>(p);
      task.alternation = alternation;
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
    const std::vector<LowerLevelOutcome> outcomes = backend.Solve(tasks, stop_requested);
    if (outcomes.size() != pair_count) {
      result.termination = "lower-level backend returned " + std::to_string(outcomes.size()) + " outcomes for " +
                           std::to_string(pair_count) + " pairs";
      return result;
    }
    Change change;
    for (std::size_t p = 0; p < pair_count; ++p) {
      change.Include(outcomes[p].T_camera_lidar, lower[p]);
      lower[p] = outcomes[p].T_camera_lidar;
      lower_cost[p] = outcomes[p].cost;
      record.lower_evaluations.push_back(outcomes[p].summary.evaluations);
      result.total_evaluations += outcomes[p].summary.evaluations;
      record.lower_gradient_evaluations.push_back(outcomes[p].gradient_evaluations);
      result.total_gradient_evaluations += outcomes[p].gradient_evaluations;
    }

    // Upper level (eq. 14), per lidar, over the pairs of that lidar.
    record.upper_cost.assign(problem.lidars.size(), 0.0);
    for (std::size_t l = 0; l < problem.lidars.size(); ++l) {
      std::vector<std::size_t> members;
      for (std::size_t p = 0; p < pair_count; ++p) {
        if (problem.pairs[p].lidar == static_cast<int>(l)) members.push_back(p);
      }
      if (members.empty()) continue;
      UpperLevelProblem upper_problem;
      // The reference camera: the base camera if it sees this lidar, else the first.
      upper_problem.base_camera = 0;
      for (std::size_t m = 0; m < members.size(); ++m) {
        if (problem.pairs[members[m]].camera == problem.base_camera) upper_problem.base_camera = static_cast<int>(m);
      }
      const int reference = problem.pairs[members[static_cast<std::size_t>(upper_problem.base_camera)]].camera;
      for (const std::size_t p : members) {
        const int camera = problem.pairs[p].camera;
        UpperLevelCamera entry;
        entry.T_base_camera = problem.cameras[static_cast<std::size_t>(camera)].T_base_camera;
        // Relative uncertainty between the reference camera and this one.
        entry.sigma = (camera_sigma(camera).array().square() +
                       (reference == problem.base_camera ? Vector6d::Zero() : camera_sigma(reference)).array().square())
                          .sqrt()
                          .matrix();
        entry.T_camera_lidar_lower = lower[p];
        entry.penalty_information = information[p];
        upper_problem.cameras.push_back(entry);
        upper_problem.T_camera_lidar_start.push_back(upper[p]);
      }
      const UpperLevelSolution solution = SolveUpperLevel(upper_problem);
      if (!solution.converged) {
        result.termination = "upper level failed for lidar " + problem.lidars[l].name + ": " + solution.message;
        return result;
      }
      record.upper_cost[l] = solution.final_cost;
      for (std::size_t m = 0; m < members.size(); ++m) {
        change.Include(solution.T_camera_lidar[m], upper[members[m]]);
        upper[members[m]] = solution.T_camera_lidar[m];
      }
      // T_base_lidar from the reference camera's pair, through its known transform.
      result.T_base_lidar[l] = problem.cameras[static_cast<std::size_t>(reference)].T_base_camera *
                               upper[members[static_cast<std::size_t>(upper_problem.base_camera)]];
    }

    Change disagreement;
    for (std::size_t p = 0; p < pair_count; ++p) disagreement.Include(lower[p], upper[p]);
    record.T_camera_lidar_lower = lower;
    record.T_camera_lidar_upper = upper;
    record.lower_cost = lower_cost;
    record.max_change_translation_m = change.translation_m;
    record.max_change_rotation_rad = change.rotation_rad;
    record.max_disagreement_translation_m = disagreement.translation_m;
    record.max_disagreement_rotation_rad = disagreement.rotation_rad;
    record.elapsed_s = elapsed_s();
    result.history.push_back(record);
    result.alternations = alternation + 1;
    if (progress) progress(record);

    if (out_of_time) {
      std::ostringstream message;
      message << "time budget of " << options.time_budget_s << " s ran out during alternation " << alternation + 1
              << "; the best estimate so far is returned";
      result.termination = message.str();
      break;
    }
    const bool settled = change.translation_m <= options.stop_translation_m &&
                         change.rotation_rad <= options.stop_rotation_rad &&
                         disagreement.translation_m <= options.stop_translation_m &&
                         disagreement.rotation_rad <= options.stop_rotation_rad;
    if (alternation > 0 && alternation + 1 >= options.min_alternations && settled) {
      result.termination = "converged after " + std::to_string(alternation + 1) +
                           " alternations: both levels moved and disagree less than the stop thresholds";
      break;
    }
  }
  if (result.termination.empty()) {
    result.termination = "reached the maximum of " + std::to_string(options.max_alternations) + " alternations";
  }
  result.T_camera_lidar_upper = upper;
  result.T_camera_lidar_lower = lower;
  result.pair_cost = lower_cost;
  result.success = true;
  return result;
}

}  // namespace scenecal
