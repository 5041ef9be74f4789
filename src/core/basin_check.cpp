#include "core/basin_check.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>

#include <fmt/format.h>

#include "core/gradient_solver.hpp"
#include "core/validation.hpp"

namespace scenecal {
namespace {

// Each pair's per-scene costs at T_base_lidar (visibility as last refreshed).
std::vector<std::vector<SceneEvaluation>> EvaluateEachScene(const std::vector<const PairCost*>& pairs,
                                                            const Eigen::Isometry3d& T_base_lidar) {
  std::vector<std::vector<SceneEvaluation>> scenes;
  for (const PairCost* pair : pairs) scenes.push_back(pair->EvaluateScenes(pair->Camera().T_camera_base() * T_base_lidar));
  return scenes;
}

// The joint cost (EvaluateJoint: the mean over the pairs with a used scene of
// each pair's mean over its used scenes, summed in the same order) from
// EvaluateEachScene's costs, so that an end's cost and its scenes' come from
// one evaluation.
double JointFromScenes(const std::vector<std::vector<SceneEvaluation>>& scenes) {
  double sum = 0.0;
  int pairs = 0;
  for (const std::vector<SceneEvaluation>& pair : scenes) {
    double pair_sum = 0.0;
    int used = 0;
    for (const SceneEvaluation& scene : pair) {
      if (scene.state != SceneState::kUsed) continue;
      pair_sum += scene.cost;
      ++used;
    }
    if (used == 0) continue;
    sum += pair_sum / static_cast<double>(used);
    ++pairs;
  }
  return pairs == 0 ? std::numeric_limits<double>::quiet_NaN() : sum / pairs;
}

// Standard error of the joint cost's drop from `from` to `to` (mean over the
// pairs of each pair's mean over its used scenes): each pair's from the
// spread of its scenes' drops, and the pairs' summed as fully correlated (an
// upper bound: they see the same frames).
double CostDropStandardError(const std::vector<std::vector<SceneEvaluation>>& from,
                             const std::vector<std::vector<SceneEvaluation>>& to) {
  double sum = 0.0;
  int pairs = 0;
  for (std::size_t p = 0; p < from.size() && p < to.size(); ++p) {
    std::vector<double> drops;
    for (std::size_t s = 0; s < from[p].size() && s < to[p].size(); ++s) {
      if (from[p][s].state != SceneState::kUsed || to[p][s].state != SceneState::kUsed) continue;
      const double drop = from[p][s].cost - to[p][s].cost;
      if (std::isfinite(drop)) drops.push_back(drop);
    }
    if (drops.empty()) continue;
    ++pairs;
    if (drops.size() < 2) return std::numeric_limits<double>::infinity();  // one scene: no spread to judge by
    double mean = 0.0;
    for (const double d : drops) mean += d;
    mean /= static_cast<double>(drops.size());
    double variance = 0.0;
    for (const double d : drops) variance += (d - mean) * (d - mean);
    variance /= static_cast<double>(drops.size() - 1);
    sum += std::sqrt(variance / static_cast<double>(drops.size()));
  }
  return pairs == 0 ? std::numeric_limits<double>::infinity() : sum / pairs;
}

// Sets how far `end` lies from `answer`.
void MeasureApart(const Eigen::Isometry3d& end, const Eigen::Isometry3d& answer, double* translation_m,
                  double* rotation_rad) {
  *translation_m = TranslationError(end, answer);
  *rotation_rad = RadiansFromDegrees(RotationErrorDegrees(end, answer));
}

// Folds one end's distance from the answer into the check's spread and agreement.
void CountEnd(double translation_m, double rotation_rad, const BasinCheckOptions& check_options,
              LidarBasinCheck* check) {
  check->max_translation_apart_m = std::max(check->max_translation_apart_m, translation_m);
  check->max_rotation_apart_rad = std::max(check->max_rotation_apart_rad, rotation_rad);
  check->agree = check->agree && check_options.Agrees(translation_m, rotation_rad);
}

}  // namespace

bool BasinCheckOptions::IsValid(std::string* why) const {
  if (!(std::isfinite(offset_rad) && offset_rad > 0.0 && offset_rad < kPi / 4))
    return Invalid(why, "basin check: the start offset must be in (0, 45) deg");
  if (!(std::isfinite(agree_translation_m) && agree_translation_m > 0.0))
    return Invalid(why, "basin check: the translation agreement bound must be a positive number of metres");
  if (!(std::isfinite(agree_rotation_rad) && agree_rotation_rad > 0.0))
    return Invalid(why, "basin check: the rotation agreement bound must be a positive angle");
  if (last_stages < 1) return Invalid(why, "basin check: it runs at least the last stage");
  if (!(std::isfinite(adopt_min_standard_errors) && adopt_min_standard_errors >= 0.0))
    return Invalid(why, "basin check: the standard errors a lower end must clear must be a number >= 0");
  if (!(std::isfinite(came_back_fraction) && came_back_fraction >= 0.0 && came_back_fraction < 1.0))
    return Invalid(why, "basin check: the came-back fraction of the agreement bounds must be in [0, 1)");
  if (!(std::isfinite(at_rest_fraction) && at_rest_fraction > 0.0 && at_rest_fraction < 1.0))
    return Invalid(why, "basin check: the at-rest fraction of the agreement bounds must be in (0, 1)");
  if (!(std::isfinite(scale_sigma) && scale_sigma >= 0.0 && scale_sigma < 0.2))
    return Invalid(why, "basin check: the trajectory's scale sigma must be a fraction in [0, 0.2)");
  return true;
}

LidarBasinCheck CheckLidarBasin(const std::vector<PairCost*>& owned, const LidarCalibration& answer,
                                const CalibrationOptions& options, const BasinCheckOptions& check_options,
                                const ProgressCallback& progress) {
  using Clock = std::chrono::steady_clock;
  const auto say = [&](const std::string& message) {
    if (progress) progress(message);
  };
  const int count = static_cast<int>(options.stages.size());
  const int first = count - std::clamp(check_options.last_stages, 1, count);
  // Each stage once, and L-BFGS to the middle stages' function tolerance: a
  // restart's end needs resolving only well within the agreement bounds. The
  // schedule's own last-stage tolerance and restart polish the answer along
  // the flat valley at the 1e-8 level of the cost; in the restarts they spent
  // 38-45 % of the evaluations and moved the ends by at most 0.05 cm /
  // 0.012 deg, one by 0.23 cm (simulated RobotCar and trinocular drives,
  // BENCHMARK.md, "Basin check and uncertainty").
  std::vector<OptimisationStage> stages(options.stages.begin() + first, options.stages.end());
  for (OptimisationStage& stage : stages) stage.restarts = 0;
  CalibrationOptions restart_options = options;
  restart_options.gradient.function_tolerance = options.gradient.MiddleStageFunctionTolerance();
  const OptimisationStage sharp{};  // no blur: the final stage's images

  const auto start = Clock::now();
  LidarBasinCheck check;
  check.lidar = answer.lidar;
  check.T_base_lidar_calibrated = answer.T_base_lidar;
  const std::vector<const PairCost*> pairs(owned.begin(), owned.end());
  // Sharp images and visibility at the answer: the reference every end is compared in.
  const auto prepare_at = [&](const OptimisationStage& stage, const Eigen::Isometry3d& T_base_lidar) {
    for (PairCost* pair : owned) {
      PreparePairForStage(*pair, stage, pair->Camera().T_camera_base() * T_base_lidar);
    }
  };
  prepare_at(sharp, answer.T_base_lidar);
  const std::vector<std::vector<SceneEvaluation>> answer_scenes = EvaluateEachScene(pairs, answer.T_base_lidar);
  check.cost_answer = JointFromScenes(answer_scenes);
  if (!std::isfinite(check.cost_answer)) {
    check.why = "no usable scene at the answer";
    return check;
  }
  NelderMeadOptions nelder_mead = options.nelder_mead;
  if (options.pivot_at_observed_centroid) {
    nelder_mead.pivot_source = ObservedCentroid(pairs, answer.T_base_lidar).value_or(nelder_mead.pivot_source);
  }

  const auto cost = [&](const Eigen::Isometry3d& candidate) { return EvaluateJoint(pairs, candidate); };
  const auto cost_with_gradient = [&](const Eigen::Isometry3d& candidate, Vector6d* gradient) {
    return EvaluateJointWithGradient(pairs, candidate, nelder_mead.transform_update, nelder_mead.pivot_source,
                                     gradient);
  };
  // A restart that passes near the answer is done only if the answer is where
  // the restarts' solver comes to rest: an answer that stopped short (on a
  // slope or a flat valley's side) is passed on the way to the minimum. So the
  // same run from the answer itself first; if it stays within the came-back
  // bounds (a few evaluations at a minimum), the restarts may stop early.
  bool answer_at_rest = false;
  if (check_options.came_back_fraction > 0.0) {
    Eigen::Isometry3d T = answer.T_base_lidar;
    OptimisationReport report;
    MinimiseWithLowerSolver(restart_options, stages, nelder_mead, cost, cost_with_gradient, prepare_at, &T, &report);
    check.evaluations += report.evaluations;
    check.answer_rest_evaluations = report.evaluations;
    double translation_m = 0.0, rotation_rad = 0.0;
    MeasureApart(T, answer.T_base_lidar, &translation_m, &rotation_rad);
    answer_at_rest = check_options.AtRest(translation_m, rotation_rad);
  }
  check.answer_at_rest = answer_at_rest;

  check.checked = true;
  check.agree = true;
  for (int axis = 0; axis < 3; ++axis) {
    for (const double sign : {-1.0, 1.0}) {
      BasinRestart restart;
      restart.axis = axis;
      restart.sign = sign;
      Vector6d offset = Vector6d::Zero();
      offset(3 + axis) = sign * check_options.offset_rad;
      Eigen::Isometry3d T = ApplyTransformUpdate(answer.T_base_lidar, offset, TransformUpdate::kAboutSourcePoint);
      OptimisationReport report;
      // The lowest point so far (within one stage: blurs change the cost), to stop once it is back.
      double lowest = std::numeric_limits<double>::infinity();
      Eigen::Isometry3d T_lowest = T;
      const auto track = [&](double value, const Eigen::Isometry3d& candidate) {
        if (value < lowest) {
          lowest = value;
          T_lowest = candidate;
        }
        return value;
      };
      const auto came_back = [&] {
        if (!answer_at_rest || !std::isfinite(lowest)) return false;
        double translation_m = 0.0, rotation_rad = 0.0;
        MeasureApart(T_lowest, answer.T_base_lidar, &translation_m, &rotation_rad);
        restart.came_back = check_options.CameBack(translation_m, rotation_rad);
        return restart.came_back;
      };
      MinimiseWithLowerSolver(
          restart_options, stages, nelder_mead,
          [&](const Eigen::Isometry3d& candidate) { return track(cost(candidate), candidate); },
          [&](const Eigen::Isometry3d& candidate, Vector6d* gradient) {
            return track(cost_with_gradient(candidate, gradient), candidate);
          },
          [&](const OptimisationStage& stage, const Eigen::Isometry3d& T_base_lidar) {
            lowest = std::numeric_limits<double>::infinity();
            prepare_at(stage, T_base_lidar);
          },
          &T, &report, came_back);
      restart.evaluations = report.evaluations;
      restart.T_base_lidar_end = T;
      MeasureApart(T, answer.T_base_lidar, &restart.translation_apart_m, &restart.rotation_apart_rad);
      prepare_at(sharp, answer.T_base_lidar);
      const std::vector<std::vector<SceneEvaluation>> end_scenes = EvaluateEachScene(pairs, T);
      restart.cost_end = JointFromScenes(end_scenes);
      restart.cost_drop_standard_error = CostDropStandardError(answer_scenes, end_scenes);
      check.evaluations += restart.evaluations;
      CountEnd(restart.translation_apart_m, restart.rotation_apart_rad, check_options, &check);
      say(fmt::format("basin check {}: the start turned {:+.2f} deg about base {} {} {:.2f} cm, {:.3f} deg from "
                      "the answer, cost {:.6f} (answer {:.6f})",
                      answer.lidar, sign * DegreesFromRadians(check_options.offset_rad), "xyz"[axis],
                      restart.came_back ? "came back to" : "ended", 100.0 * restart.translation_apart_m,
                      DegreesFromRadians(restart.rotation_apart_rad), restart.cost_end, check.cost_answer));
      check.restarts.push_back(restart);
    }
  }
  // The same run from the answer with every swathe's drift corrections
  // changed by `change`, then the corrections as they were. Returns where it ended.
  const auto run_with_corrections = [&](const auto& change, int* evaluations) {
    std::vector<std::vector<SwatheMotionCorrection>> saved;
    for (PairCost* pair : owned) {
      saved.push_back(pair->MotionCorrections());
      std::vector<SwatheMotionCorrection> changed = saved.back();
      for (SwatheMotionCorrection& correction : changed) change(&correction);
      pair->SetMotionCorrections(changed);
    }
    Eigen::Isometry3d T = answer.T_base_lidar;
    OptimisationReport report;
    MinimiseWithLowerSolver(restart_options, stages, nelder_mead, cost, cost_with_gradient, prepare_at, &T, &report);
    for (std::size_t p = 0; p < owned.size(); ++p) owned[p]->SetMotionCorrections(saved[p]);
    prepare_at(sharp, answer.T_base_lidar);
    *evaluations = report.evaluations;
    check.evaluations += report.evaluations;
    return T;
  };
  const auto moved_text = [&](const Eigen::Isometry3d& T) {
    double translation_m = 0.0, rotation_rad = 0.0;
    MeasureApart(T, answer.T_base_lidar, &translation_m, &rotation_rad);
    return fmt::format("{:.2f} cm, {:.3f} deg", 100.0 * translation_m, DegreesFromRadians(rotation_rad));
  };
  if (check_options.scale_sigma > 0.0) {
    // Every swathe's steps lengthened by scale_sigma on top of its own drift correction.
    const Eigen::Isometry3d T = run_with_corrections(
        [&](SwatheMotionCorrection* correction) { correction->scale += check_options.scale_sigma; },
        &check.scale_evaluations);
    check.scale_measured = true;
    check.scale_sigma = check_options.scale_sigma;
    check.T_base_lidar_scale_moved = T;
    check.scale_move_d = TransformUpdateBetween(answer.T_base_lidar, T, TransformUpdate::kAboutSourcePoint);
    say(fmt::format("basin check {}: with the trajectory's distances {:.2f} % longer the answer moved {}",
                    answer.lidar, 100.0 * check_options.scale_sigma, moved_text(T)));
  }
  if (check_options.without_drift_model) {
    const bool any_correction = std::any_of(owned.begin(), owned.end(), [](const PairCost* pair) {
      const std::vector<SwatheMotionCorrection> corrections = pair->MotionCorrections();
      return std::any_of(corrections.begin(), corrections.end(),
                         [](const SwatheMotionCorrection& correction) { return !correction.IsZero(); });
    });
    // No correction at all: the model moved nothing, and the run would be the one from the answer.
    const Eigen::Isometry3d T =
        any_correction ? run_with_corrections(
                             [](SwatheMotionCorrection* correction) { *correction = SwatheMotionCorrection{}; },
                             &check.drift_model_evaluations)
                       : answer.T_base_lidar;
    check.drift_model_measured = true;
    check.T_base_lidar_without_drift_model = T;
    check.drift_model_move_d = TransformUpdateBetween(answer.T_base_lidar, T, TransformUpdate::kAboutSourcePoint);
    say(fmt::format("basin check {}: with the drift corrections removed the answer moved {}", answer.lidar,
                    moved_text(T)));
  }
  check.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return check;
}

int BetterRestart(const LidarBasinCheck& check, const BasinCheckOptions& check_options, double min_cost_drop) {
  if (!check.checked || check.agree) return -1;
  int best = -1;
  double best_cost = check.cost_answer - min_cost_drop;
  for (std::size_t i = 0; i < check.restarts.size(); ++i) {
    const BasinRestart& restart = check.restarts[i];
    const bool apart = !check_options.Agrees(restart.translation_apart_m, restart.rotation_apart_rad);
    const double cost = restart.cost_end;
    const bool clear = check.cost_answer - cost > check_options.adopt_min_standard_errors *
                                                     restart.cost_drop_standard_error;
    if (apart && clear && std::isfinite(cost) && cost < best_cost) {
      best_cost = cost;
      best = static_cast<int>(i);
    }
  }
  return best;
}

void AdoptRestart(int index, const BasinCheckOptions& check_options, LidarBasinCheck* check,
                  Eigen::Isometry3d* T_base_lidar) {
  const BasinRestart& adopted = check->restarts.at(static_cast<std::size_t>(index));
  check->adopted_restart = index;
  check->T_base_lidar_calibrated = *T_base_lidar;
  check->cost_calibrated = check->cost_answer;
  *T_base_lidar = adopted.T_base_lidar_end;
  check->cost_answer = adopted.cost_end;
  MeasureApart(check->T_base_lidar_calibrated, *T_base_lidar, &check->calibrated_translation_apart_m,
               &check->calibrated_rotation_apart_rad);
  check->max_translation_apart_m = check->max_rotation_apart_rad = 0.0;
  check->agree = true;
  CountEnd(check->calibrated_translation_apart_m, check->calibrated_rotation_apart_rad, check_options, check);
  for (BasinRestart& restart : check->restarts) {
    MeasureApart(restart.T_base_lidar_end, *T_base_lidar, &restart.translation_apart_m, &restart.rotation_apart_rad);
    CountEnd(restart.translation_apart_m, restart.rotation_apart_rad, check_options, check);
  }
}

std::vector<Eigen::Isometry3d> EndsBesideAnswer(const LidarBasinCheck& check) {
  std::vector<Eigen::Isometry3d> ends;
  for (std::size_t i = 0; i < check.restarts.size(); ++i) {
    const BasinRestart& restart = check.restarts[i];
    const bool adopted = static_cast<int>(i) == check.adopted_restart;
    ends.push_back(adopted || restart.came_back ? check.T_base_lidar_calibrated : restart.T_base_lidar_end);
  }
  return ends;
}

}  // namespace scenecal
