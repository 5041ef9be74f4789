// The upper level (paper eq. 14) against cases with known answers.
#include <gtest/gtest.h>

#include "core/upper_level.hpp"

namespace scenecal {
namespace {

const Eigen::Isometry3d kT_base_right = TransformFromTuple((Vector6d() << 0.24, 0, 0, 0, 0, 0).finished());
const Eigen::Isometry3d kT_base_lidar = TransformFromTuple((Vector6d() << -0.3, 1.2, -4.0, -2.84, 0.06, -0.36).finished());

UpperLevelProblem StereoProblem(const Eigen::Isometry3d& implied_left, const Eigen::Isometry3d& implied_right,
                                const Vector6d& right_sigma, double penalty_sigma_t, double penalty_sigma_r) {
  UpperLevelProblem problem;
  UpperLevelCamera left;
  left.T_camera_lidar_lower = implied_left;  // T_base_left = I
  left.penalty_information = PenaltyInformation(penalty_sigma_t, penalty_sigma_r);
  UpperLevelCamera right;
  right.T_base_camera = kT_base_right;
  right.sigma = right_sigma;
  right.T_camera_lidar_lower = kT_base_right.inverse() * implied_right;
  right.penalty_information = left.penalty_information;
  problem.cameras = {left, right};
  return problem;
}

TEST(UpperLevel, ConsistentLowerSolutionsAreKept) {
  const UpperLevelProblem problem = StereoProblem(kT_base_lidar, kT_base_lidar, Vector6d::Zero(), 0.01, 0.01);
  const UpperLevelSolution solution = SolveUpperLevel(problem);
  ASSERT_TRUE(solution.converged) << solution.message;
  EXPECT_LT(TranslationError(solution.T_base_lidar, kT_base_lidar), 1e-9);
  EXPECT_LT(RotationErrorDegrees(solution.T_base_lidar, kT_base_lidar), 1e-7);
  EXPECT_LT(TranslationError(solution.T_camera_lidar[1], problem.cameras[1].T_camera_lidar_lower), 1e-9);
  EXPECT_LT(solution.final_cost, 1e-12);
}

// The answer does not depend on the penalty's scale: consistent lower
// solutions 10 cm / 3 deg from the start are reached with a weak coupling (a
// large sigma, the first alternations) as with a stiff one.
TEST(UpperLevel, ReachesConsistentLowerSolutionsWhateverThePenaltyScale) {
  const Eigen::Isometry3d start = ExpSE3((Vector6d() << 0.06, -0.05, 0.06, 0.03, -0.03, 0.03).finished()) * kT_base_lidar;
  for (const double sigma : {0.01, 5.0, 500.0, 1e6}) {
    UpperLevelProblem problem = StereoProblem(kT_base_lidar, kT_base_lidar, Vector6d::Zero(), sigma, sigma);
    problem.T_camera_lidar_start = {start, kT_base_right.inverse() * start};
    const UpperLevelSolution solution = SolveUpperLevel(problem);
    ASSERT_TRUE(solution.converged) << solution.message;
    EXPECT_LT(TranslationError(solution.T_base_lidar, kT_base_lidar), 1e-6) << "sigma " << sigma << ": " << solution.message;
    EXPECT_LT(RotationErrorDegrees(solution.T_base_lidar, kT_base_lidar), 1e-4) << "sigma " << sigma;
  }
}

TEST(UpperLevel, HardConstraintAveragesEqualWeightLowerSolutions) {
  // The two pairs imply T_base_lidar 2 cm apart along x: the exact constraint
  // and equal penalties put the answer half way.
  Eigen::Isometry3d implied_right = kT_base_lidar;
  implied_right.translation().x() += 0.02;
  const UpperLevelSolution solution =
      SolveUpperLevel(StereoProblem(kT_base_lidar, implied_right, Vector6d::Zero(), 0.01, 0.01));
  ASSERT_TRUE(solution.converged) << solution.message;
  Eigen::Isometry3d expected = kT_base_lidar;
  expected.translation().x() += 0.01;
  EXPECT_LT(TranslationError(solution.T_base_lidar, expected), 1e-7);
  // Both pairs now satisfy the known transform exactly.
  EXPECT_LT(TranslationError(kT_base_right * solution.T_camera_lidar[1], solution.T_base_lidar), 1e-9);
  // Cost: two residuals of 1 cm at sigma 1 cm.
  EXPECT_NEAR(solution.final_cost, 2.0, 1e-5);
}

TEST(UpperLevel, UnequalPenaltiesWeightTheAverage) {
  Eigen::Isometry3d implied_right = kT_base_lidar;
  implied_right.translation().y() += 0.03;
  // Rotation held stiff: a rotation seen from the right camera, 0.24 m off the
  // base, would otherwise trade against translation.
  UpperLevelProblem problem = StereoProblem(kT_base_lidar, implied_right, Vector6d::Zero(), 0.01, 1e-6);
  problem.cameras[1].penalty_information = PenaltyInformation(0.02, 1e-6);  // translation weight 1/4 of the left's
  const UpperLevelSolution solution = SolveUpperLevel(problem);
  ASSERT_TRUE(solution.converged) << solution.message;
  // Weighted mean: (1 * 0 + 0.25 * 3 cm) / 1.25 = 0.6 cm.
  EXPECT_NEAR(solution.T_base_lidar.translation().y() - kT_base_lidar.translation().y(), 0.006, 1e-7);
}

TEST(UpperLevel, LooseKnownTransformLeavesPairsAlone) {
  Eigen::Isometry3d implied_right = kT_base_lidar;
  implied_right.translation().z() += 0.02;
  implied_right.linear() = ExpSO3(Eigen::Vector3d(0.0, 0.003, 0.0)) * implied_right.linear();
  const Vector6d loose = (Vector6d() << 10, 10, 10, 10, 10, 10).finished();
  const UpperLevelSolution solution = SolveUpperLevel(StereoProblem(kT_base_lidar, implied_right, loose, 0.001, 0.001));
  ASSERT_TRUE(solution.converged) << solution.message;
  EXPECT_LT(TranslationError(solution.T_base_lidar, kT_base_lidar), 1e-6);
  EXPECT_LT(TranslationError(kT_base_right * solution.T_camera_lidar[1], implied_right), 1e-6);
}

TEST(UpperLevel, TightSoftConstraintApproachesTheHardOne) {
  Eigen::Isometry3d implied_right = kT_base_lidar;
  implied_right.translation().x() += 0.02;
  implied_right.linear() = ExpSO3(Eigen::Vector3d(0.002, 0.0, 0.001)) * implied_right.linear();
  const UpperLevelSolution hard = SolveUpperLevel(StereoProblem(kT_base_lidar, implied_right, Vector6d::Zero(), 0.01, 0.01));
  const Vector6d tight = Vector6d::Constant(1e-7);
  const UpperLevelSolution soft = SolveUpperLevel(StereoProblem(kT_base_lidar, implied_right, tight, 0.01, 0.01));
  ASSERT_TRUE(hard.converged && soft.converged);
  EXPECT_LT(TranslationError(hard.T_base_lidar, soft.T_base_lidar), 1e-6);
  EXPECT_LT(RotationErrorDegrees(hard.T_base_lidar, soft.T_base_lidar), 1e-4);
}

TEST(UpperLevel, RejectsInvalidProblems) {
  UpperLevelProblem empty;
  EXPECT_FALSE(SolveUpperLevel(empty).converged);
  UpperLevelProblem problem = StereoProblem(kT_base_lidar, kT_base_lidar, Vector6d::Zero(), 0.01, 0.01);
  problem.base_camera = 2;
  EXPECT_FALSE(SolveUpperLevel(problem).converged);
  problem.base_camera = 0;
  problem.cameras[1].penalty_information = -Matrix6d::Identity();
  const UpperLevelSolution solution = SolveUpperLevel(problem);
  EXPECT_FALSE(solution.converged);
  EXPECT_NE(solution.message.find("positive definite"), std::string::npos);
}

}  // namespace
}  // namespace scenecal
