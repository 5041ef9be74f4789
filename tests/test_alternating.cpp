// The alternating scheme (paper eq. 12-14) on costs with known minima.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <thread>

#include <gtest/gtest.h>

#include "core/alternating.hpp"
#include "core/calibrate_alternating.hpp"

namespace scenecal {
namespace {

const Eigen::Isometry3d kT_base_right = TransformFromTuple((Vector6d() << 0.24, 0, 0, 0, 0, 0).finished());
const Eigen::Isometry3d kT_base_lidar_true =
    TransformFromTuple((Vector6d() << -0.3, 1.2, -4.0, -2.84, 0.06, -0.36).finished());

// A bowl with its minimum at T_min: scale * sum_k (e_k / width_k)^2, e = Log(T * T_min^-1).
PairObjective Bowl(const Eigen::Isometry3d& T_min, double scale, const Vector6d& width) {
  PairObjective objective;
  objective.cost = [=](const Eigen::Isometry3d& T) {
    const Vector6d e = LogSE3(T * T_min.inverse()).cwiseQuotient(width);
    return scale * e.squaredNorm();
  };
  return objective;
}

// The same bowl about the lidar's own origin and axes, e = Log(T_min^-1 * T), as
// an image cost of the lidar's points is: a turn about the lidar's origin moves
// them by the angle, whatever the lever arm to the camera.
PairObjective LidarBowl(const Eigen::Isometry3d& T_min, double scale, const Vector6d& width) {
  PairObjective objective;
  objective.cost = [=](const Eigen::Isometry3d& T) {
    const Vector6d e = LogSE3(T_min.inverse() * T).cwiseQuotient(width);
    return scale * e.squaredNorm();
  };
  return objective;
}

AlternatingProblem StereoProblem(const Eigen::Isometry3d& initial) {
  AlternatingProblem problem;
  problem.cameras = {{"left", Eigen::Isometry3d::Identity(), std::nullopt}, {"right", kT_base_right, std::nullopt}};
  problem.lidars = {{"rear", initial}};
  problem.pairs = {{0, 0}, {1, 0}};
  return problem;
}

Eigen::Isometry3d Perturbed() {
  return ExpSE3((Vector6d() << 0.06, -0.05, 0.04, 0.02, -0.03, 0.025).finished()) * kT_base_lidar_true;
}

const Vector6d kWidth = (Vector6d() << 0.05, 0.05, 0.05, 0.02, 0.02, 0.02).finished();

// Bowls whose minima disagree: the right pair's implies a lidar 2 cm further along z than the left's.
std::vector<PairObjective> InconsistentStereoObjectives() {
  Eigen::Isometry3d implied_right = kT_base_lidar_true;
  implied_right.translation().z() += 0.02;
  return {Bowl(kT_base_lidar_true, 1.0, kWidth), Bowl(kT_base_right.inverse() * implied_right, 1.0, kWidth)};
}

TEST(Alternating, ConsistentPairsConvergeToTheTruthAndTheLevelsAgree) {
  const AlternatingProblem problem = StereoProblem(Perturbed());
  ThreadLowerLevelBackend backend({Bowl(kT_base_lidar_true, 1.0, kWidth),
                                   Bowl(kT_base_right.inverse() * kT_base_lidar_true, 1.0, kWidth)});
  AlternatingOptions options;
  int progress_calls = 0;
  const AlternatingResult result =
      SolveAlternating(problem, options, backend, [&](const AlternationRecord&) { ++progress_calls; });
  ASSERT_TRUE(result.success) << result.termination;
  EXPECT_EQ(progress_calls, result.alternations);
  EXPECT_EQ(static_cast<int>(result.history.size()), result.alternations);
  EXPECT_LT(TranslationError(result.T_base_lidar[0], kT_base_lidar_true), 1e-3);
  EXPECT_LT(RotationErrorDegrees(result.T_base_lidar[0], kT_base_lidar_true), 0.02);
  for (std::size_t p = 0; p < 2; ++p) {
    EXPECT_LT(TranslationError(result.T_camera_lidar_lower[p], result.T_camera_lidar_upper[p]), 1e-3);
    EXPECT_LT(RotationErrorDegrees(result.T_camera_lidar_lower[p], result.T_camera_lidar_upper[p]), 0.01);
  }
  // The penalty shrinks by sqrt(w) per alternation.
  ASSERT_GE(result.history.size(), 2u);
  EXPECT_NEAR(result.history[1].sigma_translation_m / result.history[0].sigma_translation_m,
              std::sqrt(options.covariance_shrink), 1e-12);
}

TEST(Alternating, InconsistentPairsMeetInBetweenUnderTheKnownTransform) {
  const AlternatingProblem problem = StereoProblem(Perturbed());
  ThreadLowerLevelBackend backend(InconsistentStereoObjectives());
  AlternatingOptions options;
  options.max_alternations = 30;
  const AlternatingResult result = SolveAlternating(problem, options, backend);
  ASSERT_TRUE(result.success) << result.termination;
  const double z_offset = result.T_base_lidar[0].translation().z() - kT_base_lidar_true.translation().z();
  EXPECT_GT(z_offset, 0.003);
  EXPECT_LT(z_offset, 0.017);
  // The known transform holds within a few of its sigmas (default 0.5 mm).
  const Eigen::Isometry3d implied_by_right = kT_base_right * result.T_camera_lidar_upper[1];
  EXPECT_LT(TranslationError(implied_by_right, result.T_base_lidar[0]), 0.003);
}

// When the levels end apart, the result's warning says what to change, and the
// number of alternations it names does close the gap (pairs 2 cm inconsistent,
// as a wrong inter-camera transform makes them).
TEST(Alternating, LevelsApartWarningNamesEnoughAlternations) {
  const AlternatingProblem problem = StereoProblem(Perturbed());
  ThreadLowerLevelBackend backend(InconsistentStereoObjectives());
  AlternatingOptions options;
  options.max_alternations = 12;
  options.stage_alternations = 6;  // the stages on the first ones: only more alternations are missing
  const AlternatingResult short_run = SolveAlternating(problem, options, backend);
  ASSERT_TRUE(short_run.success) << short_run.termination;
  ASSERT_EQ(short_run.alternations, 12) << short_run.termination;
  const std::optional<LevelsApart> apart = CheckLevelsApart(options, short_run.history.back(), false);
  ASSERT_TRUE(apart.has_value()) << "levels " << short_run.history.back().max_disagreement_translation_m
                                 << " m apart";
  EXPECT_EQ(apart->remedy, LevelsApart::Remedy::kMoreAlternations);
  const int suggested = apart->suggested_alternations;
  EXPECT_GT(suggested, options.max_alternations);
  const std::string warning = DescribeLevelsApart(*apart);
  EXPECT_NE(warning.find(std::to_string(suggested) + " alternations"), std::string::npos) << warning;
  EXPECT_EQ(warning.find("--"), std::string::npos) << "the core names no command-line option: " << warning;

  AlternatingOptions longer = options;
  longer.max_alternations = suggested;
  const AlternatingResult long_run = SolveAlternating(problem, longer, backend);
  ASSERT_TRUE(long_run.success) << long_run.termination;
  EXPECT_FALSE(CheckLevelsApart(longer, long_run.history.back(), false).has_value())
      << long_run.history.back().max_disagreement_translation_m << " m / "
      << long_run.history.back().max_disagreement_rotation_rad << " rad apart after " << long_run.alternations;
  EXPECT_NE(long_run.termination.find("converged"), std::string::npos) << long_run.termination;

  // Stages over every alternation: keep them on the first ones; a time budget: raise it.
  AlternatingOptions all_stages = options;
  all_stages.stage_alternations = 0;
  const std::optional<LevelsApart> staged = CheckLevelsApart(all_stages, short_run.history.back(), false);
  ASSERT_TRUE(staged.has_value());
  EXPECT_EQ(staged->remedy, LevelsApart::Remedy::kStagesOnFirstAlternations);
  EXPECT_EQ(staged->suggested_stage_alternations, 12);
  EXPECT_EQ(staged->suggested_alternations, 18);
  const std::optional<LevelsApart> budget = CheckLevelsApart(options, short_run.history.back(), true);
  ASSERT_TRUE(budget.has_value());
  EXPECT_EQ(budget->remedy, LevelsApart::Remedy::kLargerTimeBudget);
}

// The penalty's sigmas are the lidar's: a turn about the lidar's own origin
// costs (angle / sigma_phi)^2 and a shift of that origin (shift / sigma_t)^2,
// however far the lidar is from the camera. Stated in the camera-frame
// difference instead, the turn also pays its lever-arm shift at sigma_t.
TEST(Alternating, PenaltyInTheLidarFrameChargesATurnAboutTheLidarByItsAngle) {
  const Eigen::Isometry3d T_camera_lidar = kT_base_lidar_true;  // the lidar ~4.2 m from the camera
  const double sigma_t = 0.5, sigma_phi = 0.5, angle = 0.003, shift = 0.01;
  const auto penalty = [&](PenaltyFrame frame, const Vector6d& lidar_twist) {
    const Eigen::Isometry3d moved = T_camera_lidar * ExpSE3(lidar_twist);  // about the lidar's origin, in its axes
    const Vector6d difference = LogSE3(moved * T_camera_lidar.inverse());
    return difference.dot(PairPenaltyInformation(sigma_t, sigma_phi, frame, T_camera_lidar) * difference);
  };
  for (int axis = 0; axis < 3; ++axis) {
    const Vector6d turn = angle * Vector6d::Unit(3 + axis);
    const Vector6d slide = shift * Vector6d::Unit(axis);
    EXPECT_NEAR(penalty(PenaltyFrame::kLidar, turn), std::pow(angle / sigma_phi, 2), 1e-12);
    EXPECT_NEAR(penalty(PenaltyFrame::kLidar, slide), std::pow(shift / sigma_t, 2), 1e-12);
    EXPECT_NEAR(penalty(PenaltyFrame::kCamera, slide), std::pow(shift / sigma_t, 2), 1e-12);
  }
  // About the lidar's x axis the lever arm is ~4 m: the camera-frame statement charges ~17x.
  const double ratio = penalty(PenaltyFrame::kCamera, angle * Vector6d::Unit(3)) /
                       penalty(PenaltyFrame::kLidar, angle * Vector6d::Unit(3));
  EXPECT_GT(ratio, 10.0);
  PenaltyFrame parsed = PenaltyFrame::kLidar;
  ASSERT_TRUE(ParsePenaltyFrame(PenaltyFrameName(PenaltyFrame::kCamera), &parsed));
  EXPECT_EQ(parsed, PenaltyFrame::kCamera);
  EXPECT_FALSE(ParsePenaltyFrame("base", &parsed));
}

// Flat pair costs about the lidar's origin (as NID is: 1e-3 over a width)
// whose minima differ by a 0.23 deg turn of the lidar about its own x axis,
// ~4 m from the cameras. With the paper's schedule the camera-frame penalty
// charges that turn ~17x and holds the lower levels back; the lidar-frame
// penalty lets the upper estimate reach the joint optimum (half way).
TEST(Alternating, LidarFramePenaltyFollowsATurnThatTheCameraFramePenaltyHoldsBack) {
  const Eigen::Isometry3d implied_right = kT_base_lidar_true * ExpSE3(0.004 * Vector6d::Unit(3));
  const Eigen::Isometry3d midway = kT_base_lidar_true * ExpSE3(0.002 * Vector6d::Unit(3));
  const auto solve = [&](PenaltyFrame frame) {
    ThreadLowerLevelBackend backend({LidarBowl(kT_base_lidar_true, 1e-3, kWidth),
                                     LidarBowl(kT_base_right.inverse() * implied_right, 1e-3, kWidth)});
    AlternatingOptions options;
    options.penalty_frame = frame;
    return SolveAlternating(StereoProblem(Perturbed()), options, backend);
  };
  const AlternatingResult lidar = solve(PenaltyFrame::kLidar);
  const AlternatingResult camera = solve(PenaltyFrame::kCamera);
  ASSERT_TRUE(lidar.success) << lidar.termination;
  ASSERT_TRUE(camera.success) << camera.termination;
  const double lidar_error = RotationErrorDegrees(lidar.T_base_lidar[0], midway);
  const double camera_error = RotationErrorDegrees(camera.T_base_lidar[0], midway);
  std::printf("rotation from the joint optimum: lidar frame %.4f deg, camera frame %.4f deg\n", lidar_error,
              camera_error);
  EXPECT_LT(lidar_error, 0.02);
  EXPECT_GT(camera_error, 2.0 * lidar_error);
}

TEST(Alternating, StopsEarlyWhenSettled) {
  // Start at the truth: nothing moves, so it stops once the levels agree.
  const AlternatingProblem problem = StereoProblem(kT_base_lidar_true);
  ThreadLowerLevelBackend backend({Bowl(kT_base_lidar_true, 1.0, kWidth),
                                   Bowl(kT_base_right.inverse() * kT_base_lidar_true, 1.0, kWidth)});
  AlternatingOptions options;
  options.stop_translation_m = 1e-3;
  options.stop_rotation_rad = 1e-3;
  const AlternatingResult result = SolveAlternating(problem, options, backend);
  ASSERT_TRUE(result.success);
  EXPECT_LT(result.alternations, options.max_alternations);
  EXPECT_NE(result.termination.find("converged"), std::string::npos) << result.termination;
}

TEST(Alternating, TimeBudgetEndsWithTheBestEstimateSoFar) {
  const AlternatingProblem problem = StereoProblem(Perturbed());
  PairObjective slow = Bowl(kT_base_lidar_true, 1.0, kWidth);
  const auto fast_cost = slow.cost;
  slow.cost = [fast_cost](const Eigen::Isometry3d& T) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return fast_cost(T);
  };
  PairObjective slow_right = Bowl(kT_base_right.inverse() * kT_base_lidar_true, 1.0, kWidth);
  ThreadLowerLevelBackend backend({slow, slow_right});
  AlternatingOptions options;
  options.time_budget_s = 0.3;
  const AlternatingResult result = SolveAlternating(problem, options, backend);
  ASSERT_TRUE(result.success) << result.termination;
  EXPECT_NE(result.termination.find("time budget"), std::string::npos) << result.termination;
  EXPECT_LT(result.alternations, options.max_alternations);
  // Still better than the start.
  EXPECT_LT(TranslationError(result.T_base_lidar[0], kT_base_lidar_true),
            TranslationError(Perturbed(), kT_base_lidar_true));
}

TEST(Alternating, TwoLidarsThreeCamerasSolveIndependently) {
  AlternatingProblem problem;
  const Eigen::Isometry3d T_base_centre = TransformFromTuple((Vector6d() << 0.12, 0, 0, 0, 0, 0).finished());
  problem.cameras = {{"left", Eigen::Isometry3d::Identity(), std::nullopt},
                     {"centre", T_base_centre, std::nullopt},
                     {"right", kT_base_right, std::nullopt}};
  const Eigen::Isometry3d front_true = TransformFromTuple((Vector6d() << 0.1, 1.3, 0.2, -0.04, -1.45, 0.03).finished());
  problem.lidars = {{"rear", Perturbed()}, {"front", ExpSE3(Vector6d::Constant(0.01)) * front_true}};
  std::vector<PairObjective> objectives;
  for (int lidar = 0; lidar < 2; ++lidar) {
    for (int camera = 0; camera < 3; ++camera) {
      problem.pairs.push_back({camera, lidar});
      const Eigen::Isometry3d truth = lidar == 0 ? kT_base_lidar_true : front_true;
      objectives.push_back(Bowl(problem.cameras[static_cast<std::size_t>(camera)].T_camera_base() * truth, 1.0, kWidth));
    }
  }
  ThreadLowerLevelBackend backend(std::move(objectives));
  const AlternatingResult result = SolveAlternating(problem, AlternatingOptions{}, backend);
  ASSERT_TRUE(result.success) << result.termination;
  EXPECT_LT(TranslationError(result.T_base_lidar[0], kT_base_lidar_true), 1e-3);
  EXPECT_LT(TranslationError(result.T_base_lidar[1], front_true), 1e-3);
  EXPECT_EQ(result.T_camera_lidar_upper.size(), 6u);
}

TEST(Alternating, DeterministicForTheSameInput) {
  const auto run = [] {
    ThreadLowerLevelBackend backend({Bowl(kT_base_lidar_true, 1.0, kWidth),
                                     Bowl(kT_base_right.inverse() * kT_base_lidar_true, 2.0, kWidth)});
    return SolveAlternating(StereoProblem(Perturbed()), AlternatingOptions{}, backend);
  };
  const AlternatingResult a = run();
  const AlternatingResult b = run();
  ASSERT_EQ(a.alternations, b.alternations);
  EXPECT_EQ((a.T_base_lidar[0].matrix() - b.T_base_lidar[0].matrix()).cwiseAbs().maxCoeff(), 0.0);
}

// The coarse-to-fine stages' step scales reach each alternation's lower-level
// tasks (before the penalty-sigma cap), and the batch hook sees every batch
// whole before any of its tasks is solved.
TEST(Alternating, StepScalesAndTheBatchHookReachTheLowerLevel) {
  std::vector<std::vector<LowerLevelTask>> batches;
  std::atomic<int> hooked_alternation{-1};
  std::atomic<int> early_runs{0};  // lower levels prepared before their batch's hook ran
  PairObjective left = Bowl(kT_base_lidar_true, 1.0, kWidth);
  left.prepare = [&](const Eigen::Isometry3d&, int alternation) {
    if (hooked_alternation.load() != alternation) ++early_runs;
  };
  ThreadLowerLevelBackend backend({left, Bowl(kT_base_right.inverse() * kT_base_lidar_true, 1.0, kWidth)},
                                  [&](const std::vector<LowerLevelTask>& tasks) {
                                    batches.push_back(tasks);
                                    hooked_alternation = tasks.front().alternation;
                                  });
  AlternatingOptions options;
  options.max_alternations = 3;
  options.min_alternations = 3;
  options.lower_step_scale = {1.0, 0.3};  // the third alternation falls back to 1
  const AlternatingResult result = SolveAlternating(StereoProblem(Perturbed()), options, backend);
  ASSERT_TRUE(result.success) << result.termination;
  ASSERT_EQ(batches.size(), 3u);
  EXPECT_EQ(early_runs.load(), 0);
  for (std::size_t i = 0; i < batches.size(); ++i) {
    ASSERT_EQ(batches[i].size(), 2u);
    EXPECT_EQ(batches[i][0].alternation, static_cast<int>(i));
    const double scale = i == 1 ? 0.3 : 1.0;
    EXPECT_DOUBLE_EQ(batches[i][0].options.initial_step_translation_m, scale * options.lower.initial_step_translation_m);
    EXPECT_DOUBLE_EQ(batches[i][1].gradient.initial_step_rotation_rad,
                     scale * options.lower_gradient.initial_step_rotation_rad);
  }
  AlternatingOptions bad;
  bad.lower_step_scale = {1.0, 0.0};
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("step scales"), std::string::npos) << why;
}

// The adaptive schedule: an alternation whose levels barely moved goes on at the
// next stage's first position (every stage is still visited, the batch hook sees
// each stage start), in the last stage two positions on; the answer is the fixed
// schedule's, from fewer lower-level solves.
TEST(Alternating, AdaptiveScheduleSkipsSettledAlternationsAndEndsWhereTheFixedOneDoes) {
  const auto solve = [](bool skip_settled, std::vector<int>* positions) {
    ThreadLowerLevelBackend backend({Bowl(kT_base_lidar_true, 1.0, kWidth),
                                     Bowl(kT_base_right.inverse() * kT_base_lidar_true, 1.0, kWidth)},
                                    [positions](const std::vector<LowerLevelTask>& tasks) {
                                      positions->push_back(tasks.front().alternation);
                                    });
    AlternatingOptions options;
    options.max_alternations = 40;
    options.stage_starts = {7, 14};
    options.min_alternations = 15;
    options.skip_settled = skip_settled;
    return SolveAlternating(StereoProblem(Perturbed()), options, backend);
  };
  std::vector<int> fixed_positions;
  std::vector<int> adaptive_positions;
  const AlternatingResult fixed = solve(false, &fixed_positions);
  const AlternatingResult adaptive = solve(true, &adaptive_positions);
  ASSERT_TRUE(fixed.success) << fixed.termination;
  ASSERT_TRUE(adaptive.success) << adaptive.termination;
  for (std::size_t i = 0; i < fixed_positions.size(); ++i) EXPECT_EQ(fixed_positions[i], static_cast<int>(i));
  EXPECT_EQ(static_cast<int>(adaptive_positions.size()), adaptive.alternations);
  EXPECT_LT(adaptive.alternations, fixed.alternations);
  for (const int stage_start : {0, 7, 14}) {
    EXPECT_NE(std::find(adaptive_positions.begin(), adaptive_positions.end(), stage_start), adaptive_positions.end())
        << "stage start " << stage_start << " skipped";
  }
  for (std::size_t i = 1; i < adaptive_positions.size(); ++i) {
    const int step = adaptive_positions[i] - adaptive_positions[i - 1];
    EXPECT_GE(step, 1);
    if (step > 1) {
      const bool to_stage_start = adaptive_positions[i] == 7 || adaptive_positions[i] == 14;
      EXPECT_TRUE(to_stage_start || (adaptive_positions[i - 1] >= 14 && step == 2))
          << adaptive_positions[i - 1] << " -> " << adaptive_positions[i];
      // Only an alternation that barely moved is skipped past.
      const AlternationRecord& settled = adaptive.history[i - 1];
      EXPECT_LE(settled.max_change_translation_m, 10.0 * AlternatingOptions{}.stop_translation_m);
    }
    EXPECT_EQ(adaptive.history[i].alternation, adaptive_positions[i]);
  }
  EXPECT_LT(TranslationError(adaptive.T_base_lidar[0], fixed.T_base_lidar[0]), 1e-3);
  EXPECT_LT(RotationErrorDegrees(adaptive.T_base_lidar[0], fixed.T_base_lidar[0]), 0.01);
  EXPECT_NE(adaptive.termination.find("schedule position"), std::string::npos) << adaptive.termination;
}

// The push-broom presets' schedule: 3 stages spread over 20 of at most 40
// alternations, adaptive.
CalibrationOptions PushBroomSchedule() {
  CalibrationOptions options;
  options.stages = {{1.0, 0.004, 2}, {0.3, 0.0015, 1}, {0.1, 0.0, 1}};
  options.alternating.max_alternations = 40;
  options.alternating.stage_alternations = 20;
  options.alternating.skip_settled = true;
  return options;
}

// A coarser stage counts as settled at moves as many times larger as its steps
// are than the last stage's: 3 stages with step scales 1, 0.3 and 0.1 settle
// at 10, 3 and 1 x (settle_factor x the stop thresholds).
TEST(Alternating, CoarseStagesSettleAtLargerMoves) {
  const AlternatingOptions options = AlternatingOptionsFor(PushBroomSchedule());
  ASSERT_EQ(options.stage_starts, (std::vector<int>{7, 14}));
  EXPECT_NEAR(options.StageCoarseness(0), 10.0, 1e-12);
  EXPECT_NEAR(options.StageCoarseness(6), 10.0, 1e-12);
  EXPECT_NEAR(options.StageCoarseness(7), 3.0, 1e-12);
  EXPECT_DOUBLE_EQ(options.StageCoarseness(14), 1.0);
  EXPECT_DOUBLE_EQ(options.StageCoarseness(39), 1.0);
  EXPECT_DOUBLE_EQ(options.StageCoarseness(100), 1.0);  // past the schedule: the last stage
  const double t = options.settle_factor * options.stop_translation_m;
  const double r = options.settle_factor * options.stop_rotation_rad;
  // Moves of 5 x the last stage's threshold: settled in the first two stages, not in the last.
  EXPECT_TRUE(options.Settled(3, 5.0 * t, 5.0 * r));
  EXPECT_FALSE(options.Settled(8, 5.0 * t, 5.0 * r));
  EXPECT_TRUE(options.Settled(8, 2.9 * t, 2.9 * r));
  EXPECT_FALSE(options.Settled(15, 1.1 * t, 0.5 * r));
  EXPECT_FALSE(options.Settled(15, 0.5 * t, 1.1 * r));
  EXPECT_TRUE(options.Settled(15, t, r));
  EXPECT_FALSE(options.Settled(3, 11.0 * t, 0.0));
  // Without step scales (the thread backend's own tests) every stage settles alike.
  AlternatingOptions plain;
  EXPECT_DOUBLE_EQ(plain.StageCoarseness(0), 1.0);
  EXPECT_FALSE(plain.Settled(0, 2.0 * t, 0.0));
}

// The calibration's stages give the schedule's stage starts: 3 stages over 20 alternations begin at 0, 7, 14.
TEST(Alternating, StageStartsFollowTheStagesSpread) {
  const AlternatingOptions alternating = AlternatingOptionsFor(PushBroomSchedule());
  EXPECT_TRUE(alternating.skip_settled);
  EXPECT_EQ(alternating.stage_starts, (std::vector<int>{7, 14}));
  EXPECT_EQ(alternating.min_alternations, 15);
}

TEST(Alternating, RejectsInvalidInput) {
  AlternatingProblem problem = StereoProblem(Perturbed());
  problem.pairs.push_back({5, 0});
  ThreadLowerLevelBackend backend({});
  const AlternatingResult result = SolveAlternating(problem, AlternatingOptions{}, backend);
  EXPECT_FALSE(result.success);
  EXPECT_NE(result.termination.find("invalid"), std::string::npos);
  AlternatingOptions bad;
  bad.covariance_shrink = 1.5;
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_FALSE(why.empty());
}

}  // namespace
}  // namespace scenecal
