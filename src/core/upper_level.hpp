// The paper's upper level (equation 14), for one lidar: with every lower-level
// solution T^_p fixed, find the pairs' T_p = T_camera_lidar that minimise
//   sum_p |T_p (-) T^_p|^2_{P_pL}  +  sum_(a,b) |e_ab|^2_{P_ab},
//   e_ab = (T_aL (-) T_bL) (-) T_ab_known,
// a small nonlinear least-squares problem solved with Ceres.
//
// Differences are SE(3) logarithms, A (-) B = Log(A * B^-1), tangent ordering
// [rho (m); phi (rad)]. Internally each camera p is represented by the lidar
// pose it implies in the base frame, Y_p = T_base_p * T_p; then
// e_(base,b) = Log(Y_base * Y_b^-1) exactly (T_base_base = I), and a camera
// whose known transform is exact (sigma all zero: a hard constraint) simply
// shares the base camera's Y.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/geometry.hpp"

namespace scenecal {

struct UpperLevelCamera {
  Eigen::Isometry3d T_base_camera = Eigen::Isometry3d::Identity();  // known (factory) transform
  // 1-sigma of T_base_camera (m, m, m, rad, rad, rad); all zeros = exact (hard
  // constraint). Ignored for the base camera, which defines the base frame.
  Vector6d sigma = Vector6d::Zero();
  Eigen::Isometry3d T_camera_lidar_lower = Eigen::Isometry3d::Identity();  // T^_p, held fixed
  // (P_pL^i)^-1: information of the coupling penalty, in [rho; phi] coordinates.
  Matrix6d penalty_information = Matrix6d::Identity();
};

struct UpperLevelProblem {
  std::vector<UpperLevelCamera> cameras;
  int base_camera = 0;  // index into cameras of the base frame's camera
  // Starting values of T_p (e.g. the previous upper solution); empty = the lower solutions.
  std::vector<Eigen::Isometry3d> T_camera_lidar_start;
};

struct UpperLevelSolution {
  std::vector<Eigen::Isometry3d> T_camera_lidar;  // T_p per camera, same order as the problem
  Eigen::Isometry3d T_base_lidar = Eigen::Isometry3d::Identity();  // implied by the base camera
  double final_cost = 0.0;  // sum of squared weighted residuals
  int iterations = 0;
  bool converged = false;
  std::string message;  // Ceres' brief report or why the problem was rejected
};

// Returns converged = false with a message for an invalid problem (no cameras,
// base index out of range, non-finite input, non-positive-definite information).
UpperLevelSolution SolveUpperLevel(const UpperLevelProblem& problem);

// Information matrix diag(1/sigma_t^2 x3, 1/sigma_phi^2 x3).
Matrix6d PenaltyInformation(double sigma_translation_m, double sigma_rotation_rad);

}  // namespace scenecal
