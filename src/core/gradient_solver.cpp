#include "core/gradient_solver.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include <ceres/first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>
#include <ceres/iteration_callback.h>
#include <ceres/manifold.h>
#include <tbb/parallel_for.h>

#include "core/interrupt.hpp"
#include "core/pair_cost.hpp"
#include "core/validation.hpp"

namespace scenecal {

const char* LowerSolverName(LowerSolver solver) { return EnumName(kLowerSolverNames, solver); }

bool ParseLowerSolver(const std::string& name, LowerSolver* solver) {
  return ParseEnumName(kLowerSolverNames, name, solver);
}

bool GradientSolverOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) return Invalid(why, "max_iterations must be at least 1");
  if (lbfgs_rank < 1) return Invalid(why, "lbfgs_rank must be at least 1");
  if (line_search_max_steps < 1) return Invalid(why, "line_search_max_steps must be at least 1");
  if (!(function_tolerance >= 0.0) || !(coarse_function_tolerance >= 0.0) || !(gradient_tolerance >= 0.0) ||
      !(parameter_tolerance >= 0.0))
    return Invalid(why, "tolerances must be >= 0");
  if (!(initial_step_translation_m > 0.0) || !(initial_step_rotation_rad > 0.0))
    return Invalid(why, "initial steps must be > 0 (metres, radians)");
  if (!pivot_source.allFinite()) return Invalid(why, "pivot_source must be finite");
  if (!(std::isfinite(run_radius_translation_m) && run_radius_translation_m >= 0.0) ||
      !(std::isfinite(run_radius_rotation_rad) && run_radius_rotation_rad >= 0.0 && run_radius_rotation_rad < kPi))
    return Invalid(why, "run radii must be >= 0 (metres) and in [0, 180) deg (0 = no limit)");
  return true;
}

std::string GradientSolverSummary::BriefReport() const {
  std::ostringstream out;
  out << "lbfgs iterations " << iterations << ", evaluations " << evaluations << " (" << gradient_evaluations
      << " with gradient), cost " << initial_value << " -> "
      << final_value << ", " << time_s << " s, " << (converged ? "converged" : "not converged") << ": "
      << termination;
  return out.str();
}

namespace {

// ((distance - radius) / radius)^2 beyond each radius of the run's start (none when the radius is 0).
double RunWall(const Eigen::Isometry3d& T_start, const Eigen::Isometry3d& T, const GradientSolverOptions& options) {
  double wall = 0.0;
  const auto add = [&](double distance, double radius) {
    if (radius > 0.0 && distance > radius) wall += std::pow((distance - radius) / radius, 2);
  };
  add((T.translation() - T_start.translation()).norm(), options.run_radius_translation_m);
  add(Eigen::AngleAxisd(T.linear() * T_start.linear().transpose()).angle(), options.run_radius_rotation_rad);
  return wall;
}

// The cost plus the run's wall about T_start (the cost itself when no radius
// is set). The wall's gradient by central differences: a few arithmetic
// operations each, against a pass over the swathes.
CostWithGradient WithRunWall(const CostWithGradient& cost, const GradientSolverOptions& options,
                             const Eigen::Isometry3d& T_start) {
  if (options.run_radius_translation_m <= 0.0 && options.run_radius_rotation_rad <= 0.0) return cost;
  return [&cost, options, T_start](const Eigen::Isometry3d& T, Vector6d* gradient) {
    double value = cost(T, gradient);
    const double wall = RunWall(T_start, T, options);
    if (!std::isfinite(value) || wall == 0.0) return value;
    if (gradient != nullptr) {
      *gradient += CentralDifferenceGradient(
          [&](const Eigen::Isometry3d& X) { return RunWall(T_start, X, options); }, T, options.transform_update,
          options.pivot_source, Vector6d::Constant(1e-6));
    }
    return value + wall;
  };
}

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
    return TransformUpdateBetween(from, to, options_.transform_update, options_.pivot_source).cwiseQuotient(scale_);
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

struct EvaluationCounts {
  std::atomic<int> evaluations{0};
  std::atomic<int> gradient_evaluations{0};
  bool start_not_finite = false;  // the first evaluation (at the start, x = 0) failed
};

class TransformCost final : public ceres::FirstOrderFunction {
 public:
  TransformCost(const TransformState* state, const CostWithGradient* cost, EvaluationCounts* counts)
      : state_(state), cost_(cost), counts_(counts) {}
  int NumParameters() const override { return 6; }

  // Evaluates the start (x = 0) with its gradient and from then on reports
  // the cost multiplied by 1 / (the start's largest scaled gradient), so that
  // the first iteration's step (Ceres: the gradient itself, when its max norm
  // is below 1) is one typical step (the parameter scales) along the steepest
  // axis. Without it the first step was |gradient| scaled units: NID gradients
  // are ~1e-5 per typical step near a minimum, so the first step gained less
  // than the cost's rounding, and the following steps, sized by Ceres from
  // that gain, stayed as small (world 1: joint stuck 0.233 deg from the truth;
  // measured on the simulated RobotCar drive). The L-BFGS directions and the later steps
  // do not depend on a constant factor on the cost.
  void NormaliseAtStart() {
    double value = 0.0;
    Vector6d gradient = Vector6d::Zero();
    const Vector6d zero = Vector6d::Zero();
    if (!Evaluate(zero.data(), &value, gradient.data())) return;  // Ceres meets the failure again
    start_value_ = value;
    start_gradient_ = gradient;
    has_start_ = true;
    const double largest = gradient.cwiseAbs().maxCoeff();
    if (largest > 0.0 && std::isfinite(largest)) value_scale_ = 1.0 / largest;
  }
  double ValueScale() const { return value_scale_; }

  bool Evaluate(const double* x, double* value, double* gradient) const override {
    if (has_start_ && gradient != nullptr && Eigen::Map<const Vector6d>(x).isZero(0.0)) {
      *value = value_scale_ * start_value_;  // Ceres' own first evaluation: already known
      Eigen::Map<Vector6d> out(gradient);
      out = value_scale_ * start_gradient_;
      return true;
    }
    // Never throw through Ceres: a failed evaluation makes it back off at
    // once, and the callback below ends the solve.
    if (InterruptRequested()) return false;
    const bool first = counts_->evaluations++ == 0;
    Vector6d local = Vector6d::Zero();
    if (gradient != nullptr) ++counts_->gradient_evaluations;
    // No gradient requested: the plain (cheaper) evaluation.
    *value = (*cost_)(state_->Transform(x), gradient != nullptr ? &local : nullptr);
    if (!std::isfinite(*value)) {
      if (first) counts_->start_not_finite = true;
      return false;  // Ceres backs off the step
    }
    *value *= value_scale_;
    if (gradient != nullptr) {
      Eigen::Map<Vector6d> out(gradient);
      out = value_scale_ * state_->Scale().cwiseProduct(local);
    }
    return true;
  }

 private:
  const TransformState* state_;
  const CostWithGradient* cost_;
  EvaluationCounts* counts_;
  double value_scale_ = 1.0;  // constant within a run (set before Ceres starts)
  bool has_start_ = false;
  double start_value_ = 0.0;     // unscaled cost at x = 0
  Vector6d start_gradient_;      // unscaled (in value) gradient at x = 0, scaled parameters
};

// Ends the solve (successfully: the state so far is kept) once the caller asks.
class StopCallback final : public ceres::IterationCallback {
 public:
  explicit StopCallback(const StopRequested* stop_requested) : stop_requested_(stop_requested) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    if (InterruptRequested()) return ceres::SOLVER_ABORT;  // MinimiseWithGradient then throws Interrupted
    if (*stop_requested_ && (*stop_requested_)()) {
      stopped = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool stopped = false;

 private:
  const StopRequested* stop_requested_;
};

}  // namespace

GradientSolverSummary MinimiseWithGradient(const CostWithGradient& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* transform, const StopRequested& stop_requested) {
  const auto start_time = std::chrono::steady_clock::now();
  GradientSolverSummary summary;
  const TransformState state(*transform, options);
  EvaluationCounts counts;
  StopCallback stop_callback(&stop_requested);
  const CostWithGradient walled = WithRunWall(cost, options, *transform);
  // The problem takes ownership of the function and the manifold.
  auto* function = new TransformCost(&state, &walled, &counts);
  function->NormaliseAtStart();
  const double value_scale = function->ValueScale();
  ceres::GradientProblem problem(function, new TransformManifold(&state));
  ceres::GradientProblemSolver::Options solver_options;
  solver_options.line_search_direction_type = ceres::LBFGS;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.logging_type = ceres::SILENT;
  solver_options.callbacks.push_back(&stop_callback);
  // Oren's scaling of the initial inverse Hessian: the NID's curvature in the
  // scaled parameters is far from 1 (a quasi-Newton step is often 10-1000
  // times the gradient), and with the identity the line search stalls in the
  // flat valleys of the cost (measured on simulated RobotCar pairs: the
  // simplex's cost in half its evaluations with it; stuck 4 cm away without).
  solver_options.use_approximate_eigenvalue_bfgs_scaling = options.approximate_eigenvalue_scaling;
  solver_options.max_lbfgs_rank = options.lbfgs_rank;
  solver_options.max_num_line_search_step_size_iterations = options.line_search_max_steps;
  Vector6d x = Vector6d::Zero();
  ceres::GradientProblemSolver::Summary ceres_summary;
  ceres::Solve(solver_options, problem, x.data(), &ceres_summary);
  ThrowIfInterrupted();
  *transform = state.Transform(x.data());
  summary.iterations = static_cast<int>(ceres_summary.iterations.size()) - 1;  // iteration 0 is the start
  summary.evaluations = counts.evaluations.load();
  summary.gradient_evaluations = counts.gradient_evaluations.load();
  summary.start_not_finite = counts.start_not_finite;
  summary.initial_value = ceres_summary.initial_cost / value_scale;
  summary.final_value = ceres_summary.final_cost / value_scale;
  summary.stopped = stop_callback.stopped;
  summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
  summary.termination = stop_callback.stopped ? "stop requested (e.g. time budget)" : ceres_summary.message;
  summary.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return summary;
}

GradientSolverSummary MinimiseWithGradient(const PairCost& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* T_camera_lidar, const StopRequested& stop_requested) {
  const CostWithGradient function = [&](const Eigen::Isometry3d& T, Vector6d* gradient) {
    if (gradient == nullptr) return cost.Evaluate(T);
    return cost.EvaluateWithGradient(T, options.transform_update, options.pivot_source, gradient);
  };
  return MinimiseWithGradient(function, options, T_camera_lidar, stop_requested);
}

Vector6d BaseGradientFromCameraGradient(const Eigen::Isometry3d& T_base_camera, TransformUpdate update,
                                        const Vector6d& gradient_camera) {
  const Eigen::Isometry3d T_camera_base = T_base_camera.inverse();
  // A left twist of T_base_lidar is the left twist Ad(T_camera_base) xi of T_camera_lidar.
  if (update == TransformUpdate::kLeftTwist) return AdjointSE3(T_camera_base).transpose() * gradient_camera;
  // About a lidar point the update's axes only turn with the frames.
  const Eigen::Matrix3d R_cb_transposed = T_camera_base.linear().transpose();
  Vector6d gradient_base;
  gradient_base.head<3>() = R_cb_transposed * gradient_camera.head<3>();
  gradient_base.tail<3>() = R_cb_transposed * gradient_camera.tail<3>();
  return gradient_base;
}

double EvaluateJointWithGradient(const std::vector<const PairCost*>& pairs, const Eigen::Isometry3d& T_base_lidar,
                                 TransformUpdate update, const Eigen::Vector3d& pivot_lidar, Vector6d* gradient) {
  std::vector<double> costs(pairs.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<Vector6d> gradients(pairs.size(), Vector6d::Zero());
  tbb::parallel_for(std::size_t{0}, pairs.size(), [&](std::size_t p) {
    if (pairs[p]->UsedSceneCount() == 0) return;
    const Eigen::Isometry3d& T_base_camera = pairs[p]->Camera().T_base_camera;
    const Eigen::Isometry3d T_camera_lidar = T_base_camera.inverse() * T_base_lidar;
    if (gradient == nullptr) {
      costs[p] = pairs[p]->Evaluate(T_camera_lidar);
      return;
    }
    Vector6d gradient_camera;
    costs[p] = pairs[p]->EvaluateWithGradient(T_camera_lidar, update, pivot_lidar, &gradient_camera);
    gradients[p] = BaseGradientFromCameraGradient(T_base_camera, update, gradient_camera);
  });
  // Pairs in order: deterministic, and the same sum as EvaluateJoint.
  double sum = 0.0;
  Vector6d gradient_sum = Vector6d::Zero();
  int counted = 0;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    if (std::isnan(costs[p])) continue;
    sum += costs[p];
    gradient_sum += gradients[p];
    ++counted;
  }
  if (gradient != nullptr) *gradient = counted == 0 ? Vector6d::Zero() : Vector6d(gradient_sum / counted);
  return counted == 0 ? std::numeric_limits<double>::quiet_NaN() : sum / counted;
}

Vector6d CentralDifferenceGradient(const std::function<double(const Eigen::Isometry3d&)>& cost,
                                   const Eigen::Isometry3d& T, TransformUpdate update,
                                   const Eigen::Vector3d& pivot_source, const Vector6d& steps) {
  Vector6d gradient;
  for (int axis = 0; axis < 6; ++axis) {
    Vector6d delta = Vector6d::Zero();
    delta[axis] = steps[axis];
    gradient[axis] = (cost(ApplyTransformUpdate(T, delta, update, pivot_source)) -
                      cost(ApplyTransformUpdate(T, -delta, update, pivot_source))) /
                     (2.0 * steps[axis]);
  }
  return gradient;
}

}  // namespace scenecal
