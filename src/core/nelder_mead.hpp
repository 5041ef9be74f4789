// Nelder-Mead simplex search (the paper's lower-level optimiser), derivative
// free, for costs that are cheap to evaluate but not smooth (hard-binned NID).
//
// Two entry points:
//  - MinimiseNelderMead: a generic n-dimensional minimisation.
//  - MinimiseOverTransform: minimises a cost of a rigid transform T_a_b over a
//    LOCAL 6-parameter update delta = [rho; phi] (metres, radians, tangent
//    ordering of geometry.hpp) with both parts expressed along the axes of
//    frame a (for T_camera_lidar: the camera frame). Two forms:
//      kLeftTwist:       T = ExpSE3(delta) * T_0 (rotation about a's origin)
//      kAboutSourcePoint (default): R = ExpSO3(phi) * R_0 and the pivot point
//        q (given in frame b, default b's origin) moves by rho:
//        T * q = T_0 * q + rho. Rotation and translation are decoupled: a
//        lidar 3 m behind the camera does not move 5 cm when it turns 1
//        degree, and with q at the centroid of the observed points a
//        rotation leaves the observed points in place on average.
//
// Standard coefficients (reflection 1, expansion 2, contraction 1/2, shrink
// 1/2); the initial simplex is x0 plus one step along each axis.
#pragma once

#include <functional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scenecal {

enum class TransformUpdate { kAboutSourcePoint, kLeftTwist };

// The transform reached by the local update delta from T_0 (see above).
Eigen::Isometry3d ApplyTransformUpdate(const Eigen::Isometry3d& T_0, const Eigen::Matrix<double, 6, 1>& delta,
                                       TransformUpdate update,
                                       const Eigen::Vector3d& pivot_source = Eigen::Vector3d::Zero());
// Its inverse: the local update that takes `from` to `to`
// (ApplyTransformUpdate(from, TransformUpdateBetween(from, to, ...), ...) == to).
Eigen::Matrix<double, 6, 1> TransformUpdateBetween(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to,
                                                   TransformUpdate update,
                                                   const Eigen::Vector3d& pivot_source = Eigen::Vector3d::Zero());

struct NelderMeadOptions {
  // Initial simplex edges of the transform search: metres for the translation
  // part and radians for the rotation part of the local update.
  double initial_step_translation_m = 0.05;
  double initial_step_rotation_rad = 0.02;
  int max_iterations = 200;    // the paper runs 200
  int max_evaluations = 0;     // 0: no cap on cost evaluations
  // Stop when the spread of the cost over the simplex vertices is at most this.
  double function_tolerance = 1e-7;
  // Stop when every vertex lies within these distances of the best vertex, per
  // parameter: metres (translation) and radians (rotation) for transforms. The
  // generic entry point uses per-dimension tolerances given by its caller.
  double simplex_tolerance_translation_m = 2e-4;
  double simplex_tolerance_rotation_rad = 2e-5;
  // Parameterisation of MinimiseOverTransform.
  TransformUpdate transform_update = TransformUpdate::kAboutSourcePoint;
  Eigen::Vector3d pivot_source = Eigen::Vector3d::Zero();  // q of kAboutSourcePoint, metres in frame b

  bool IsValid(std::string* why = nullptr) const;
};

enum class NelderMeadTermination {
  kFunctionTolerance,  // cost spread over the simplex below tolerance
  kSimplexTolerance,   // simplex shrank below tolerance
  kMaxIterations,
  kMaxEvaluations,
  kStopRequested,      // the caller's stop callback returned true (e.g. time budget)
  kNonFiniteCost,      // the cost at the start point is not finite
};
const char* NelderMeadTerminationName(NelderMeadTermination termination);

struct NelderMeadSummary {
  int iterations = 0;
  int evaluations = 0;
  double initial_value = 0.0;
  double final_value = 0.0;
  NelderMeadTermination termination = NelderMeadTermination::kMaxIterations;

  // One line: "iterations 200, evaluations 312, cost 0.91 -> 0.87, max iterations".
  std::string BriefReport() const;
};

// Optional callback polled once per iteration; returning true stops the search
// (the best point so far is kept).
using StopRequested = std::function<bool()>;

// Minimises cost over x, starting at *x, with initial simplex steps `steps`
// (one per dimension, non-zero) and per-dimension simplex tolerances
// `tolerances` (absolute). *x receives the best point found. Non-finite cost
// values are treated as +infinity (worse than any finite value).
NelderMeadSummary MinimiseNelderMead(const std::function<double(const Eigen::VectorXd&)>& cost,
                                     const Eigen::VectorXd& steps, const Eigen::VectorXd& tolerances,
                                     const NelderMeadOptions& options, Eigen::VectorXd* x,
                                     const StopRequested& stop_requested = {});

// Minimises cost(T) over T = ApplyTransformUpdate(T_0, delta,
// options.transform_update), with T_0 = *transform on entry; *transform
// receives the best transform found.
NelderMeadSummary MinimiseOverTransform(const std::function<double(const Eigen::Isometry3d&)>& cost,
                                        const NelderMeadOptions& options, Eigen::Isometry3d* transform,
                                        const StopRequested& stop_requested = {});

}  // namespace scenecal
