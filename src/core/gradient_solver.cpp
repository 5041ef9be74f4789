#include "core/gradient_solver.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>

#include <ceres/first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>
#include <ceres/manifold.h>

#include "core/pair_cost.hpp"

namespace scenecal {

bool GradientSolverOptions::IsValid(std::string* why) const {
  const auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(function_tolerance >= 0.0) || !(gradient_tolerance >= 0.0) || !(parameter_tolerance >= 0.0))
    return fail("tolerances must be >= 0");
  if (!(initial_step_translation_m > 0.0) || !(initial_step_rotation_rad > 0.0))
    return fail("initial steps must be > 0 (metres, radians)");
  if (!pivot_source.allFinite()) return fail("pivot_source must be finite");
  return true;
}

std::string GradientSolverSummary::BriefReport() const {
  std::ostringstream out;
  out << "lbfgs iterations " << iterations << ", evaluations " << evaluations << ", cost " << initial_value << " -> "
      << final_value << ", " << time_s << " s, " << (converged ? "converged" : "not converged") << ": "
      << termination;
  return out.str();
}

namespace {

// The state x (6) is the scaled local update from the start transform:
// T(x) = ApplyTransformUpdate(T_0, scale .* x). Plus(x, d) applies a further
// local update at T(x), so the tangent gradient Ceres needs is exactly the
// local gradient at T(x) (scaled): PlusJacobian is reported as the identity.
class TransformState {
 public:
  TransformState(const Eigen::Isometry3d& T_0, const GradientSolverOptions& options) : T_0_(T_0), options_(options) {
    scale_ << Eigen::Vector3d::Constant(options.initial_step_translation_m),
        Eigen::Vector3d::Constant(options.initial_step_rotation_rad);
  }

  Eigen::Isometry3d Transform(const double* x) const {
    return ApplyTransformUpdate(T_0_, scale_.cwiseProduct(Eigen::Map<const Vector6d>(x)), options_.transform_update,
                                options_.pivot_source);
  }
  // Local update (scaled) taking `from` to `to`: the inverse of ApplyTransformUpdate.
  Vector6d ScaledUpdate(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to) const {
    Vector6d delta;
    if (options_.transform_update == TransformUpdate::kLeftTwist) {
      delta = LogSE3(to * from.inverse());
    } else {
      delta.head<3>() = to * options_.pivot_source - from * options_.pivot_source;
      delta.tail<3>() = LogSO3(to.linear() * from.linear().transpose());
    }
    return delta.cwiseQuotient(scale_);
  }
  const Vector6d& Scale() const { return scale_; }
  const Eigen::Isometry3d& Start() const { return T_0_; }
  const GradientSolverOptions& Options() const { return options_; }

 private:
  Eigen::Isometry3d T_0_;
  GradientSolverOptions options_;
  Vector6d scale_;
};

class TransformManifold final : public ceres::Manifold {
 public:
  explicit TransformManifold(const TransformState* state) : state_(state) {}
  int AmbientSize() const override { return 6; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    const Eigen::Isometry3d T = state_->Transform(x);
    const Eigen::Isometry3d moved =
        ApplyTransformUpdate(T, state_->Scale().cwiseProduct(Eigen::Map<const Vector6d>(delta)),
                             state_->Options().transform_update, state_->Options().pivot_source);
    Eigen::Map<Vector6d> out(x_plus_delta);
    out = state_->ScaledUpdate(state_->Start(), moved);
    return true;
  }
  bool PlusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(jacobian).setIdentity();
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Vector6d> out(y_minus_x);
    out = state_->ScaledUpdate(state_->Transform(x), state_->Transform(y));
    return true;
  }
  bool MinusJacobian(const double*, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(jacobian).setIdentity();
    return true;
  }

 private:
  const TransformState* state_;
};

class TransformCost final : public ceres::FirstOrderFunction {
 public:
  TransformCost(const TransformState* state, const CostWithGradient* cost, std::atomic<int>* evaluations)
      : state_(state), cost_(cost), evaluations_(evaluations) {}
  int NumParameters() const override { return 6; }
  bool Evaluate(const double* x, double* value, double* gradient) const override {
    ++*evaluations_;
    Vector6d local = Vector6d::Zero();
    *value = (*cost_)(state_->Transform(x), &local);
    if (!std::isfinite(*value)) return false;  // Ceres backs off the step
    if (gradient != nullptr) {
      Eigen::Map<Vector6d> out(gradient);
      out = state_->Scale().cwiseProduct(local);
    }
    return true;
  }

 private:
  const TransformState* state_;
  const CostWithGradient* cost_;
  std::atomic<int>* evaluations_;
};

}  // namespace

GradientSolverSummary MinimiseWithGradient(const CostWithGradient& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* transform) {
  const auto start_time = std::chrono::steady_clock::now();
  GradientSolverSummary summary;
  const TransformState state(*transform, options);
  std::atomic<int> evaluations{0};
  // The problem takes ownership of the function and the manifold.
  ceres::GradientProblem problem(new TransformCost(&state, &cost, &evaluations), new TransformManifold(&state));
  ceres::GradientProblemSolver::Options solver_options;
  solver_options.line_search_direction_type = ceres::LBFGS;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.logging_type = ceres::SILENT;
  Vector6d x = Vector6d::Zero();
  ceres::GradientProblemSolver::Summary ceres_summary;
  ceres::Solve(solver_options, problem, x.data(), &ceres_summary);
  *transform = state.Transform(x.data());
  summary.iterations = static_cast<int>(ceres_summary.iterations.size()) - 1;  // iteration 0 is the start
  summary.evaluations = evaluations.load();
  summary.initial_value = ceres_summary.initial_cost;
  summary.final_value = ceres_summary.final_cost;
  summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
  summary.termination = ceres_summary.message;
  summary.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return summary;
}

GradientSolverSummary MinimiseWithGradient(const PairCost& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* T_camera_lidar) {
  const CostWithGradient function = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    return cost.EvaluateWithGradient(T, options.transform_update, options.pivot_source, gradient);
  };
  return MinimiseWithGradient(function, options, T_camera_lidar);
}

}  // namespace scenecal
