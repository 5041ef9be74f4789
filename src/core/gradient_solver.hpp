// Quasi-Newton lower level: L-BFGS (ceres::GradientProblemSolver) over the
// local 6-parameter update of a transform, with analytic gradients (for the
// B-spline metric, PairCost::EvaluateWithGradient). Far fewer cost
// evaluations than the simplex when the cost is smooth.
//
// The state is a transform T; Ceres sees a 6-dimensional tangent space whose
// Plus is ApplyTransformUpdate (core/nelder_mead.hpp: same parameterisation as
// the simplex, [rho; phi] in metres and radians along the target frame's
// axes), scaled per axis by the typical steps (initial_step_*), so that the
// problem is well conditioned for the line search.
//
// Also here: the choice of lower-level solver the schemes share, the joint
// cost's gradient with respect to T_base_lidar (chain rule through the known
// camera transforms) and a central-difference gradient for costs that have
// no analytic one.
#pragma once

#include <algorithm>

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/enum_names.hpp"
#include "core/geometry.hpp"
#include "core/nelder_mead.hpp"

namespace scenecal {

class PairCost;

// The local (lower-level) optimiser of every scheme: the paper's simplex
// (Nelder-Mead, derivative free, any binning) or L-BFGS with analytic
// gradients (B-spline binning only: hard-binned costs are piecewise constant).
enum class LowerSolver { kSimplex, kLbfgs };
inline constexpr auto kLowerSolverNames =
    MakeEnumNames<LowerSolver>({{LowerSolver::kSimplex, "simplex"}, {LowerSolver::kLbfgs, "lbfgs"}});
const char* LowerSolverName(LowerSolver solver);                        // "simplex", "lbfgs"
bool ParseLowerSolver(const std::string& name, LowerSolver* solver);  // inverse; false if unknown

struct GradientSolverOptions {
  int max_iterations = 100;
  // Stop when |df| / f falls below this, or the gradient's max norm (in the
  // scaled parameters, relative to the start's) below gradient_tolerance, or
  // the step below parameter_tolerance.
  // NID near 0.95 changes by ~1e-4 along a push-broom tilt valley; at 1e-8 a
  // run could end on one short step while the cost still fell toward the
  // minimum (0.285 instead of 0.159 deg on one start, the simulated RobotCar drive).
  double function_tolerance = 1e-10;
  // The coarse-to-fine schedule's stages between its first and its last use
  // this instead (when larger): starting near the answer, they need only bring
  // it into the last stage's reach, and their tails crept along the flat
  // valley. Not the first stage: from far starts its slow descent is what
  // keeps the basin wide (cut short, a start 30 cm / 10 deg off ran away;
  // docs/findings.md, "The smooth cost is rough below a thousandth of a step").
  double coarse_function_tolerance = 1e-8;
  double MiddleStageFunctionTolerance() const { return std::max(function_tolerance, coarse_function_tolerance); }
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  // Typical step per axis: metres (translation part), radians (rotation part).
  double initial_step_translation_m = 0.05;
  double initial_step_rotation_rad = 0.02;
  TransformUpdate transform_update = TransformUpdate::kAboutSourcePoint;
  Eigen::Vector3d pivot_source = Eigen::Vector3d::Zero();  // q of kAboutSourcePoint, metres in frame b
  // How far one run may move the transform from where it started: beyond
  // either radius the cost gains ((distance - radius) / radius)^2, a smooth
  // wall (0 = no limit). Far from the truth a blurred stage's NID is nearly
  // flat, a line search can then step metres, and a pose that projects only a
  // few points can score lower than the truth (10.2 m / 40 deg off on a
  // simulated RobotCar drive): the wall keeps each run near its start, while the
  // schedule's runs together can still move further.
  double run_radius_translation_m = 0.0;
  double run_radius_rotation_rad = 0.0;
  int lbfgs_rank = 20;  // curvature pairs kept (Ceres' max_lbfgs_rank)
  // Trial steps per line search (Ceres' max_num_line_search_step_size_iterations,
  // 20 by default). Below ~1e-3 of a parameter scale the cost is rough (points
  // crossing the image border change it by ~1e-7 at a time), so the strong
  // Wolfe curvature test can fail however long the search: with 20, the
  // push-broom setting spent 50-85 % of its coarse stages' evaluations in
  // searches that found nothing better than their first few trials. An
  // exhausted search still takes the best step with a sufficient decrease.
  int line_search_max_steps = 4;
  // Scale the initial inverse Hessian by an estimate of its eigenvalue (Ceres'
  // use_approximate_eigenvalue_bfgs_scaling). Needed on NID: see the .cpp.
  bool approximate_eigenvalue_scaling = true;

  bool IsValid(std::string* why = nullptr) const;
};

struct GradientSolverSummary {
  int iterations = 0;
  int evaluations = 0;           // cost evaluations, with or without the gradient
  int gradient_evaluations = 0;  // of which also computed the gradient (nearly all: Wolfe line search)
  double initial_value = 0.0;
  double final_value = 0.0;
  bool converged = false;       // a tolerance was met (not the iteration cap, not a failure)
  bool stopped = false;         // the caller's stop callback ended the run (e.g. time budget)
  bool start_not_finite = false;  // the cost at the start could not be evaluated; nothing was done
  std::string termination;      // Ceres' message
  double time_s = 0.0;

  std::string BriefReport() const;
};

// Cost at T and, when gradient is not null, its gradient with respect to the
// local update delta at delta = 0 (ApplyTransformUpdate(T, delta, update,
// pivot_source)); return a non-finite cost when it cannot be evaluated.
using CostWithGradient = std::function<double(const Eigen::Isometry3d& T, Vector6d* gradient)>;

// Minimises cost over T starting at *transform; *transform receives the best
// transform found. stop_requested is polled once per iteration.
GradientSolverSummary MinimiseWithGradient(const CostWithGradient& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* transform, const StopRequested& stop_requested = {});

// The pair cost over T_camera_lidar (options.transform_update and pivot_source
// are passed to PairCost::EvaluateWithGradient). Use B-spline binning.
GradientSolverSummary MinimiseWithGradient(const PairCost& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* T_camera_lidar,
                                           const StopRequested& stop_requested = {});

// The gradient of a pair cost with respect to the local update of
// T_base_lidar, from its gradient with respect to the local update of
// T_camera_lidar = T_base_camera^-1 * T_base_lidar (same update kind; the
// pivot of kAboutSourcePoint is a lidar-frame point, the same for both):
//   kAboutSourcePoint: delta_camera = [R_cb rho; R_cb phi]  =>  g_base = [R_cb^T g_rho; R_cb^T g_phi]
//   kLeftTwist:        delta_camera = Ad(T_cb) delta_base    =>  g_base = Ad(T_cb)^T g_camera
// with T_cb = T_base_camera^-1 and Ad(T) = [R, [t]x R; 0, R] for [rho; phi].
Vector6d BaseGradientFromCameraGradient(const Eigen::Isometry3d& T_base_camera, TransformUpdate update,
                                        const Vector6d& gradient_camera);

// The `joint` cost (EvaluateJoint, core/pair_cost.hpp: the mean over the pairs
// with a used scene of each pair's cost at T_base_camera^-1 * T_base_lidar)
// and, when gradient is not null, its gradient with respect to the local
// update of T_base_lidar (pivot_lidar: q of kAboutSourcePoint, metres in the
// lidar frame). Same value as EvaluateJoint. NaN when no pair has a used scene.
double EvaluateJointWithGradient(const std::vector<const PairCost*>& pairs, const Eigen::Isometry3d& T_base_lidar,
                                 TransformUpdate update, const Eigen::Vector3d& pivot_lidar, Vector6d* gradient);

// Central differences of cost along each axis of the local update at T:
// (cost(T + h_k e_k) - cost(T - h_k e_k)) / 2 h_k, steps h in metres and
// radians. For cheap smooth terms (the alt penalty) or costs without an
// analytic gradient; 12 evaluations.
Vector6d CentralDifferenceGradient(const std::function<double(const Eigen::Isometry3d&)>& cost,
                                   const Eigen::Isometry3d& T, TransformUpdate update,
                                   const Eigen::Vector3d& pivot_source, const Vector6d& steps);

}  // namespace scenecal
