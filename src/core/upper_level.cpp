#include "core/upper_level.hpp"

#include <cmath>
#include <memory>

#include <ceres/ceres.h>

#include "core/interrupt.hpp"

namespace scenecal {
namespace {

// Ends a solve at the next iteration once an interruption is requested (never
// throw through Ceres); SolveUpperLevel then throws Interrupted.
class AbortWhenInterrupted final : public ceres::IterationCallback {
 public:
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return InterruptRequested() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }
};

// Y = Exp(delta) * Y0: a local update of the implied base-frame lidar pose.
Eigen::Isometry3d Update(const double* delta, const Eigen::Isometry3d& Y0) {
  return ExpSE3(Eigen::Map<const Vector6d>(delta)) * Y0;
}

// sqrt_info * Log(T_base_p^-1 * Y_p * T^_p^-1): the coupling penalty of camera p.
struct CouplingResidual {
  Eigen::Isometry3d Y0;
  Eigen::Isometry3d T_camera_base;
  Eigen::Isometry3d T_lidar_camera_lower;  // (T^_p)^-1
  Matrix6d sqrt_information;
  bool operator()(const double* delta, double* residual) const {
    const Eigen::Isometry3d T_camera_lidar = T_camera_base * Update(delta, Y0);
    Eigen::Map<Vector6d> out(residual);
    out = sqrt_information * LogSE3(T_camera_lidar * T_lidar_camera_lower);
    return true;
  }
};

// sqrt_info * Log(Y_base * Y_b^-1): the inter-camera term e_(base,b).
struct InterCameraResidual {
  Eigen::Isometry3d Y0_base;
  Eigen::Isometry3d Y0_other;
  Matrix6d sqrt_information;
  bool operator()(const double* delta_base, const double* delta_other, double* residual) const {
    Eigen::Map<Vector6d> out(residual);
    out = sqrt_information * LogSE3(Update(delta_base, Y0_base) * Update(delta_other, Y0_other).inverse());
    return true;
  }
};

bool SqrtInformation(const Matrix6d& information, Matrix6d* sqrt_information) {
  if (!information.allFinite()) return false;
  const Eigen::LLT<Matrix6d> llt(0.5 * (information + information.transpose()));
  if (llt.info() != Eigen::Success) return false;
  *sqrt_information = llt.matrixU();
  return true;
}

// Why the problem's shape cannot be solved ("" when it can).
std::string ShapeError(const UpperLevelProblem& problem) {
  const int camera_count = static_cast<int>(problem.cameras.size());
  if (camera_count == 0) return "upper level: no cameras";
  if (problem.base_camera < 0 || problem.base_camera >= camera_count) {
    return "upper level: base camera index out of range";
  }
  if (!problem.T_camera_lidar_start.empty() &&
      static_cast<int>(problem.T_camera_lidar_start.size()) != camera_count) {
    return "upper level: start values do not match the cameras";
  }
  return "";
}

ceres::Solver::Options UpperLevelSolverOptions() {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 100;
  options.function_tolerance = 1e-14;
  // Ceres' gradient test is absolute: with a weak coupling penalty (a large
  // --sigma0) the whole gradient is below any fixed bound at the start and the
  // upper level would not move; the relative function and parameter tests end it.
  options.gradient_tolerance = 0.0;
  options.parameter_tolerance = 1e-12;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  return options;
}

}  // namespace

Matrix6d PenaltyInformation(double sigma_translation_m, double sigma_rotation_rad) {
  Vector6d diagonal;
  diagonal << Eigen::Vector3d::Constant(1.0 / (sigma_translation_m * sigma_translation_m)),
      Eigen::Vector3d::Constant(1.0 / (sigma_rotation_rad * sigma_rotation_rad));
  return diagonal.asDiagonal();
}

UpperLevelSolution SolveUpperLevel(const UpperLevelProblem& problem) {
  UpperLevelSolution solution;
  const int camera_count = static_cast<int>(problem.cameras.size());
  solution.message = ShapeError(problem);
  if (!solution.message.empty()) return solution;

  // One 6-vector block per camera with a soft constraint; hard ones share the base block.
  std::vector<Vector6d> deltas(static_cast<std::size_t>(camera_count), Vector6d::Zero());
  std::vector<int> block_of(static_cast<std::size_t>(camera_count));
  std::vector<Eigen::Isometry3d> Y0(static_cast<std::size_t>(camera_count));
  for (int p = 0; p < camera_count; ++p) {
    const UpperLevelCamera& camera = problem.cameras[static_cast<std::size_t>(p)];
    const bool hard = p != problem.base_camera && camera.sigma.isZero(0.0);
    block_of[static_cast<std::size_t>(p)] = hard ? problem.base_camera : p;
    const Eigen::Isometry3d start = problem.T_camera_lidar_start.empty()
                                        ? camera.T_camera_lidar_lower
                                        : problem.T_camera_lidar_start[static_cast<std::size_t>(p)];
    Y0[static_cast<std::size_t>(p)] = camera.T_base_camera * start;
    if (!Y0[static_cast<std::size_t>(p)].matrix().allFinite() || !camera.sigma.allFinite() ||
        (camera.sigma.array() < 0).any()) {
      solution.message = "upper level: non-finite transform or negative sigma for camera " + std::to_string(p);
      return solution;
    }
  }
  // A hard camera's implied pose is parameterised around the base camera's start.
  for (int p = 0; p < camera_count; ++p) {
    if (block_of[static_cast<std::size_t>(p)] != p) Y0[static_cast<std::size_t>(p)] = Y0[static_cast<std::size_t>(problem.base_camera)];
  }

  ceres::Problem ceres_problem;
  for (int p = 0; p < camera_count; ++p) {
    const UpperLevelCamera& camera = problem.cameras[static_cast<std::size_t>(p)];
    Matrix6d sqrt_information;
    if (!SqrtInformation(camera.penalty_information, &sqrt_information)) {
      solution.message = "upper level: penalty information of camera " + std::to_string(p) +
                         " is not positive definite";
      return solution;
    }
    auto* residual = new CouplingResidual{Y0[static_cast<std::size_t>(p)], camera.T_base_camera.inverse(),
                                          camera.T_camera_lidar_lower.inverse(), sqrt_information};
    ceres_problem.AddResidualBlock(
        new ceres::NumericDiffCostFunction<CouplingResidual, ceres::CENTRAL, 6, 6>(residual), nullptr,
        deltas[static_cast<std::size_t>(block_of[static_cast<std::size_t>(p)])].data());
  }
  for (int p = 0; p < camera_count; ++p) {
    if (p == problem.base_camera || block_of[static_cast<std::size_t>(p)] != p) continue;
    const Vector6d sigma = problem.cameras[static_cast<std::size_t>(p)].sigma;
    // A zero component among non-zero ones is a very stiff (not infinite) constraint.
    const Vector6d floor = sigma.cwiseMax(1e-9);
    const Matrix6d sqrt_information = floor.cwiseInverse().asDiagonal();
    auto* residual = new InterCameraResidual{Y0[static_cast<std::size_t>(problem.base_camera)],
                                             Y0[static_cast<std::size_t>(p)], sqrt_information};
    ceres_problem.AddResidualBlock(
        new ceres::NumericDiffCostFunction<InterCameraResidual, ceres::CENTRAL, 6, 6, 6>(residual), nullptr,
        deltas[static_cast<std::size_t>(problem.base_camera)].data(), deltas[static_cast<std::size_t>(p)].data());
  }

  ceres::Solver::Options options = UpperLevelSolverOptions();
  AbortWhenInterrupted abort_when_interrupted;
  options.callbacks.push_back(&abort_when_interrupted);
  ceres::Solver::Summary summary;
  ceres::Solve(options, &ceres_problem, &summary);
  ThrowIfInterrupted();

  solution.converged = summary.IsSolutionUsable();
  solution.final_cost = 2.0 * summary.final_cost;  // Ceres reports half the sum of squares
  solution.iterations = static_cast<int>(summary.iterations.size());
  solution.message = summary.BriefReport();
  solution.T_camera_lidar.resize(static_cast<std::size_t>(camera_count));
  for (int p = 0; p < camera_count; ++p) {
    const int block = block_of[static_cast<std::size_t>(p)];
    const Eigen::Isometry3d Y = Update(deltas[static_cast<std::size_t>(block)].data(), Y0[static_cast<std::size_t>(p)]);
    solution.T_camera_lidar[static_cast<std::size_t>(p)] =
        problem.cameras[static_cast<std::size_t>(p)].T_base_camera.inverse() * Y;
  }
  solution.T_base_lidar = Update(deltas[static_cast<std::size_t>(problem.base_camera)].data(),
                                 Y0[static_cast<std::size_t>(problem.base_camera)]);
  return solution;
}

}  // namespace scenecal
