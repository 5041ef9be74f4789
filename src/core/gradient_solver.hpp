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
#pragma once

#include <functional>
#include <string>

#include <Eigen/Geometry>

#include "core/geometry.hpp"
#include "core/nelder_mead.hpp"

namespace scenecal {

class PairCost;

struct GradientSolverOptions {
  int max_iterations = 100;
  // Stop when |df| / f falls below this, or the gradient's max norm (in the
  // scaled parameters) below gradient_tolerance, or the step below parameter_tolerance.
  double function_tolerance = 1e-8;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  // Typical step per axis: metres (translation part), radians (rotation part).
  double initial_step_translation_m = 0.05;
  double initial_step_rotation_rad = 0.02;
  TransformUpdate transform_update = TransformUpdate::kAboutSourcePoint;
  Eigen::Vector3d pivot_source = Eigen::Vector3d::Zero();  // q of kAboutSourcePoint, metres in frame b

  bool IsValid(std::string* why = nullptr) const;
};

struct GradientSolverSummary {
  int iterations = 0;
  int evaluations = 0;  // cost + gradient evaluations
  double initial_value = 0.0;
  double final_value = 0.0;
  bool converged = false;      // a tolerance was met (not the iteration cap, not a failure)
  std::string termination;     // Ceres' message
  double time_s = 0.0;

  std::string BriefReport() const;
};

// Cost at T and its gradient with respect to the local update delta at
// delta = 0 (ApplyTransformUpdate(T, delta, update, pivot_source)); return a
// non-finite cost when it cannot be evaluated.
using CostWithGradient = std::function<double(const Eigen::Isometry3d& T, Vector6d* gradient)>;

// Minimises cost over T starting at *transform; *transform receives the best transform found.
GradientSolverSummary MinimiseWithGradient(const CostWithGradient& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* transform);

// The pair cost over T_camera_lidar (options.transform_update and pivot_source
// are passed to PairCost::EvaluateWithGradient). Use B-spline binning.
GradientSolverSummary MinimiseWithGradient(const PairCost& cost, const GradientSolverOptions& options,
                                           Eigen::Isometry3d* T_camera_lidar);

}  // namespace scenecal
