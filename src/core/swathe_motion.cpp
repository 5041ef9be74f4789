#include "core/swathe_motion.hpp"

#include <algorithm>
#include <cstddef>

#include "core/geometry.hpp"
#include "core/swathe.hpp"

namespace scenecal {

namespace {

// One step of the trajectory (T_a_b, a earlier than b) as corrected by
// `correction`, the rates about the travel frame's axes (columns of axes).
Eigen::Isometry3d CorrectStep(const Eigen::Isometry3d& T_a_b, const Eigen::Matrix3d& axes,
                              const SwatheMotionCorrection& correction) {
  const double length_m = T_a_b.translation().norm();
  const Eigen::Vector3d turn =
      axes * Eigen::Vector3d(correction.turn_a_rad_per_m, correction.turn_b_rad_per_m, correction.roll_rad_per_m) *
      length_m;
  Eigen::Isometry3d corrected = T_a_b;
  // The heading turns steadily along the step: its chord points half way.
  corrected.translation() = ExpSO3(0.5 * turn) * T_a_b.translation() * (1.0 + correction.scale);
  corrected.linear() = T_a_b.linear() * ExpSO3(turn);
  return corrected;
}

}  // namespace

Eigen::Matrix3d MotionAxes(const std::vector<Eigen::Isometry3d>& T_basek_basej) {
  if (T_basek_basej.empty()) return Eigen::Matrix3d::Identity();
  // From the first scan to the last (in time order): a straight chord of the travel.
  const Eigen::Vector3d travel = T_basek_basej.back().translation() - T_basek_basej.front().translation();
  if (!(travel.norm() > 1e-6)) return Eigen::Matrix3d::Identity();
  const Eigen::Vector3d forward = travel.normalized();
  Eigen::Index least = 0;
  forward.cwiseAbs().minCoeff(&least);
  Eigen::Vector3d across_a = Eigen::Vector3d::Unit(least);
  across_a = (across_a - across_a.dot(forward) * forward).normalized();
  Eigen::Matrix3d axes;
  axes << across_a, forward.cross(across_a), forward;
  return axes;
}

std::vector<Eigen::Isometry3d> CorrectSwatheMotion(const std::vector<TimeUs>& scan_t_us,
                                                   const std::vector<Eigen::Isometry3d>& T_basek_basej,
                                                   TimeUs image_t_us, const SwatheMotionCorrection& correction) {
  std::vector<Eigen::Isometry3d> corrected = T_basek_basej;
  const std::size_t n = std::min(scan_t_us.size(), T_basek_basej.size());
  if (correction.IsZero() || n == 0) return corrected;
  const Eigen::Matrix3d axes = MotionAxes(T_basek_basej);
  // The chain starts at the image pose (identity in base k) and runs forward
  // through the later scans and backward through the earlier ones.
  const std::size_t first_after =
      static_cast<std::size_t>(std::lower_bound(scan_t_us.begin(), scan_t_us.begin() + static_cast<std::ptrdiff_t>(n),
                                                image_t_us) -
                               scan_t_us.begin());
  Eigen::Isometry3d previous_given = Eigen::Isometry3d::Identity(), previous_corrected = previous_given;
  for (std::size_t j = first_after; j < n; ++j) {
    previous_corrected =
        previous_corrected * CorrectStep(previous_given.inverse() * T_basek_basej[j], axes, correction);
    previous_given = T_basek_basej[j];
    corrected[j] = previous_corrected;
  }
  Eigen::Isometry3d next_given = Eigen::Isometry3d::Identity(), next_corrected = next_given;
  for (std::size_t j = first_after; j-- > 0;) {
    next_corrected =
        next_corrected * CorrectStep(T_basek_basej[j].inverse() * next_given, axes, correction).inverse();
    next_given = T_basek_basej[j];
    corrected[j] = next_corrected;
  }
  return corrected;
}

void SceneSwathe::SetMotionCorrection(const SwatheMotionCorrection& correction) {
  motion_correction_ = correction;
  ComposeScanPoses(CorrectSwatheMotion(scan_t_us_, T_basek_basej_, image_t_us_, correction));
}

}  // namespace scenecal
