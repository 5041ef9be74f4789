// Nelder-Mead: convergence on standard problems, caps and the SE(3) wrapper.
#include <cmath>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "core/nelder_mead.hpp"

namespace scenecal {
namespace {

TEST(NelderMead, OptionsValidation) {
  NelderMeadOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.max_iterations = 0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("max_iterations"), std::string::npos);
  options = NelderMeadOptions{};
  options.initial_step_rotation_rad = -1.0;
  EXPECT_FALSE(options.IsValid(&why));
}

TEST(NelderMead, RosenbrockConverges) {
  const auto rosenbrock = [](const Eigen::VectorXd& v) {
    return 100.0 * std::pow(v[1] - v[0] * v[0], 2) + std::pow(1.0 - v[0], 2);
  };
  NelderMeadOptions options;
  options.max_iterations = 2000;
  options.function_tolerance = 1e-14;
  Eigen::VectorXd x(2);
  x << -1.2, 1.0;
  const Eigen::VectorXd steps = Eigen::VectorXd::Constant(2, 0.1);
  const Eigen::VectorXd tolerances = Eigen::VectorXd::Constant(2, 1e-8);
  const NelderMeadSummary summary = MinimiseNelderMead(rosenbrock, steps, tolerances, options, &x);
  EXPECT_NEAR(x[0], 1.0, 1e-3);
  EXPECT_NEAR(x[1], 1.0, 2e-3);
  EXPECT_LT(summary.final_value, 1e-6);
  EXPECT_LT(summary.final_value, summary.initial_value);
  EXPECT_NE(summary.termination, NelderMeadTermination::kMaxIterations);
}

TEST(NelderMead, Quadratic6DConverges) {
  // Anisotropic, correlated quadratic with minimum at `minimum`.
  Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Identity();
  for (int i = 0; i < 6; ++i) a(i, i) = 1.0 + i;
  a(0, 1) = a(1, 0) = 0.5;
  a(3, 5) = a(5, 3) = -0.8;
  Eigen::VectorXd minimum(6);
  minimum << 0.3, -0.2, 0.1, 0.05, -0.4, 0.25;
  const auto quadratic = [&](const Eigen::VectorXd& v) {
    const Eigen::VectorXd d = v - minimum;
    return d.dot(a * d) + 2.0;
  };
  NelderMeadOptions options;
  options.max_iterations = 3000;
  options.function_tolerance = 1e-16;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(6);
  const NelderMeadSummary summary = MinimiseNelderMead(quadratic, Eigen::VectorXd::Constant(6, 0.1),
                                                       Eigen::VectorXd::Constant(6, 1e-7), options, &x);
  EXPECT_LT((x - minimum).norm(), 1e-4) << summary.BriefReport();
  EXPECT_NEAR(summary.final_value, 2.0, 1e-8);
}

TEST(NelderMead, IterationCapHonoured) {
  const auto sphere = [](const Eigen::VectorXd& v) { return v.squaredNorm(); };
  NelderMeadOptions options;
  options.max_iterations = 7;
  options.function_tolerance = 0.0;
  Eigen::VectorXd x = Eigen::VectorXd::Constant(6, 3.0);
  const NelderMeadSummary summary = MinimiseNelderMead(sphere, Eigen::VectorXd::Constant(6, 0.01),
                                                       Eigen::VectorXd::Zero(6), options, &x);
  EXPECT_EQ(summary.iterations, 7);
  EXPECT_EQ(summary.termination, NelderMeadTermination::kMaxIterations);
  EXPECT_LE(summary.final_value, summary.initial_value);
  EXPECT_DOUBLE_EQ(sphere(x), summary.final_value);
}

TEST(NelderMead, EvaluationCapAndStopCallback) {
  const auto sphere = [](const Eigen::VectorXd& v) { return v.squaredNorm(); };
  NelderMeadOptions options;
  options.max_evaluations = 20;
  options.function_tolerance = 0.0;
  Eigen::VectorXd x = Eigen::VectorXd::Constant(3, 1.0);
  NelderMeadSummary summary = MinimiseNelderMead(sphere, Eigen::VectorXd::Constant(3, 0.1),
                                                 Eigen::VectorXd::Zero(3), options, &x);
  EXPECT_EQ(summary.termination, NelderMeadTermination::kMaxEvaluations);
  // The cap is checked between iterations; one iteration costs at most n + 2 evaluations.
  EXPECT_LE(summary.evaluations, 20 + 3 + 2);

  options.max_evaluations = 0;
  int polls = 0;
  x = Eigen::VectorXd::Constant(3, 1.0);
  summary = MinimiseNelderMead(sphere, Eigen::VectorXd::Constant(3, 0.1), Eigen::VectorXd::Zero(3), options, &x,
                               [&] { return ++polls > 4; });
  EXPECT_EQ(summary.termination, NelderMeadTermination::kStopRequested);
  EXPECT_EQ(summary.iterations, 4);
}

TEST(NelderMead, NonFiniteStartIsReported) {
  const auto nan_cost = [](const Eigen::VectorXd&) { return std::nan(""); };
  Eigen::VectorXd x = Eigen::VectorXd::Zero(2);
  const NelderMeadSummary summary = MinimiseNelderMead(nan_cost, Eigen::VectorXd::Constant(2, 0.1),
                                                       Eigen::VectorXd::Zero(2), NelderMeadOptions{}, &x);
  EXPECT_EQ(summary.termination, NelderMeadTermination::kNonFiniteCost);
  EXPECT_EQ(summary.evaluations, 1);
}

// A transform, a local update and a pivot for the update tests.
struct UpdateExample {
  Eigen::Isometry3d start = TransformFromTuple((Vector6d() << 1.0, -2.0, 0.5, 0.3, -0.1, 2.0).finished());
  Vector6d delta = (Vector6d() << 0.01, -0.02, 0.03, 0.02, -0.01, 0.015).finished();
  Eigen::Vector3d pivot{0.5, -3.0, 1.0};
};

TEST(NelderMead, TransformUpdateMovesThePivotByRho) {
  const UpdateExample example;
  const Eigen::Isometry3d& start = example.start;
  const Vector6d& delta = example.delta;
  const Eigen::Vector3d& pivot = example.pivot;
  const Eigen::Isometry3d moved = ApplyTransformUpdate(start, delta, TransformUpdate::kAboutSourcePoint, pivot);
  // The pivot moves by exactly rho; the rotation is ExpSO3(phi) * R_0.
  EXPECT_LT(((moved * pivot) - (start * pivot) - delta.head<3>()).norm(), 1e-12);
  EXPECT_LT((moved.linear() - ExpSO3(delta.tail<3>()) * start.linear()).norm(), 1e-12);
  // About the origin: the translation moves by rho alone.
  const Eigen::Isometry3d about_origin = ApplyTransformUpdate(start, delta, TransformUpdate::kAboutSourcePoint);
  EXPECT_LT((about_origin.translation() - start.translation() - delta.head<3>()).norm(), 1e-12);
  // The left twist: ExpSE3(delta) * T_0.
  EXPECT_TRUE(ApplyTransformUpdate(start, delta, TransformUpdate::kLeftTwist).isApprox(ExpSE3(delta) * start, 1e-12));
}

TEST(NelderMead, TransformUpdateBetweenInvertsTheUpdate) {
  const UpdateExample example;
  const Eigen::Isometry3d& start = example.start;
  const Vector6d& delta = example.delta;
  const Eigen::Vector3d& pivot = example.pivot;
  for (const TransformUpdate update : {TransformUpdate::kAboutSourcePoint, TransformUpdate::kLeftTwist}) {
    for (const Eigen::Vector3d& q : {Eigen::Vector3d::Zero().eval(), pivot}) {
      const Eigen::Isometry3d moved = ApplyTransformUpdate(start, delta, update, q);
      EXPECT_LT((TransformUpdateBetween(start, moved, update, q) - delta).norm(), 1e-12);
      EXPECT_LT(TransformUpdateBetween(start, start, update, q).norm(), 1e-15);
    }
  }
}

TEST(NelderMead, TransformWrapperRecoversATransform) {
  Vector6d truth_tuple;
  truth_tuple << 0.4, -0.3, 1.2, 0.1, -0.2, 0.3;
  const Eigen::Isometry3d truth = TransformFromTuple(truth_tuple);
  // Cost: squared distances of a few reference points mapped by T and by the truth.
  const Eigen::Matrix<double, 3, 4> points =
      (Eigen::Matrix<double, 3, 4>() << 1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 1).finished();
  const auto cost = [&](const Eigen::Isometry3d& t) {
    double sum = 0.0;
    for (int i = 0; i < 4; ++i) sum += (t * points.col(i) - truth * points.col(i)).squaredNorm();
    return sum;
  };
  Vector6d start_perturbation;
  start_perturbation << 0.05, -0.04, 0.03, 0.02, -0.015, 0.01;
  Eigen::Isometry3d estimate = ExpSE3(start_perturbation) * truth;
  NelderMeadOptions options;
  options.max_iterations = 2000;
  options.function_tolerance = 1e-18;
  options.simplex_tolerance_translation_m = 1e-9;
  options.simplex_tolerance_rotation_rad = 1e-9;
  const NelderMeadSummary summary = MinimiseOverTransform(cost, options, &estimate);
  EXPECT_LT(TranslationError(estimate, truth), 1e-5) << summary.BriefReport();
  EXPECT_LT(RotationErrorDegrees(estimate, truth), 1e-4) << summary.BriefReport();
}

}  // namespace
}  // namespace scenecal
