// The swathe's drift correction (core/swathe.hpp CorrectSwatheMotion,
// MotionAxes): the travel frame follows the motion whatever the base's axes,
// a zero correction keeps the poses, and the correction that mirrors a drift
// of the simulator's kind (scale error, turn rates across the travel, applied
// step by step as sim::OdometryDrift does) undoes it to first order, for
// scans after and before the image.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "core/swathe.hpp"

namespace scenecal {
namespace {

constexpr double kStepM = 0.1;  // a scan every 10 cm of travel

// A base whose axes are a camera's (x right, y down, z forward), rolled and
// turned a little, so that nothing lines up with the travel by accident.
Eigen::Matrix3d BaseOrientation() { return RotationFromRollPitchYaw(0.05, -0.08, 0.3); }

// The true world poses of a drive: `before_m` metres up to the image pose
// (index first_after - 1 is the last scan before it), then `after_m` metres,
// on a gentle curve; forward is the base's z axis.
std::vector<Eigen::Isometry3d> TruePoses(double before_m, double after_m, std::size_t* image_index) {
  std::vector<Eigen::Isometry3d> poses;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = BaseOrientation();
  const int steps = static_cast<int>(std::lround((before_m + after_m) / kStepM));
  *image_index = static_cast<std::size_t>(std::lround(before_m / kStepM));
  for (int i = 0; i <= steps; ++i) {
    poses.push_back(pose);
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.translation() = Eigen::Vector3d(0.0, 0.0, kStepM);
    step.linear() = ExpSO3(Eigen::Vector3d(0.0, RadiansFromDegrees(0.2) * kStepM, 0.0));  // a slow curve
    pose = pose * step;
  }
  return poses;
}

// What drifting odometry reports for those poses: every step's length scaled
// by (1 + scale_error) and the base turned by turn_rate (base frame, rad/m)
// times the step's length at its end, accumulated from the first pose.
std::vector<Eigen::Isometry3d> Drifted(const std::vector<Eigen::Isometry3d>& truth, double scale_error,
                                       const Eigen::Vector3d& turn_rate) {
  std::vector<Eigen::Isometry3d> odometry{truth.front()};
  for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
    const Eigen::Isometry3d delta = truth[i].inverse() * truth[i + 1];
    Eigen::Isometry3d drifted = delta;
    drifted.translation() *= 1.0 + scale_error;
    drifted.linear() = delta.linear() * ExpSO3(turn_rate * delta.translation().norm());
    odometry.push_back(odometry.back() * drifted);
  }
  return odometry;
}

struct Swathe {
  std::vector<TimeUs> scan_t_us;
  std::vector<Eigen::Isometry3d> T_basek_basej;
  TimeUs image_t_us = 0;
};

// The swathe of every pose but the image's, relative to the image's.
Swathe MakeSwathe(const std::vector<Eigen::Isometry3d>& poses, std::size_t image_index) {
  Swathe swathe;
  swathe.image_t_us = static_cast<TimeUs>(image_index) * 10000 + 5000;  // between two scans
  for (std::size_t i = 0; i < poses.size(); ++i) {
    swathe.scan_t_us.push_back(static_cast<TimeUs>(i) * 10000 + (i >= image_index ? 10000 : 0));
    swathe.T_basek_basej.push_back(poses[image_index].inverse() * poses[i]);
  }
  return swathe;
}

// Largest translation (m) and rotation (rad) difference between two pose lists.
std::pair<double, double> LargestDifference(const std::vector<Eigen::Isometry3d>& a,
                                            const std::vector<Eigen::Isometry3d>& b) {
  double translation = 0.0, rotation = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    translation = std::max(translation, (a[i].translation() - b[i].translation()).norm());
    rotation = std::max(rotation, LogSO3(a[i].linear().transpose() * b[i].linear()).norm());
  }
  return {translation, rotation};
}

TEST(MotionAxes, FollowTheTravelWhateverTheBaseAxes) {
  std::size_t image_index = 0;
  const std::vector<Eigen::Isometry3d> poses = TruePoses(5.0, 30.0, &image_index);
  const Swathe swathe = MakeSwathe(poses, image_index);
  const Eigen::Matrix3d axes = MotionAxes(swathe.T_basek_basej);
  EXPECT_NEAR((axes.transpose() * axes - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(axes.determinant(), 1.0, 1e-12);
  const Eigen::Vector3d chord =
      (swathe.T_basek_basej.back().translation() - swathe.T_basek_basej.front().translation()).normalized();
  EXPECT_NEAR(axes.col(2).dot(chord), 1.0, 1e-12);
  // The base moves along its z axis (slowly turning about y): forward is nearly z.
  EXPECT_GT(axes.col(2).z(), 0.99);
  // A swathe that does not move (a static scene): the base's own axes.
  const std::vector<Eigen::Isometry3d> still(4, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(MotionAxes(still).isApprox(Eigen::Matrix3d::Identity()));
}

TEST(CorrectSwatheMotion, ZeroCorrectionKeepsThePoses) {
  std::size_t image_index = 0;
  const Swathe swathe = MakeSwathe(TruePoses(5.0, 30.0, &image_index), image_index);
  const std::vector<Eigen::Isometry3d> corrected =
      CorrectSwatheMotion(swathe.scan_t_us, swathe.T_basek_basej, swathe.image_t_us, SwatheMotionCorrection{});
  ASSERT_EQ(corrected.size(), swathe.T_basek_basej.size());
  for (std::size_t i = 0; i < corrected.size(); ++i)
    EXPECT_TRUE(corrected[i].matrix() == swathe.T_basek_basej[i].matrix()) << i;
}

TEST(CorrectSwatheMotion, UndoesADriftOfScaleAndTurnRatesToFirstOrder) {
  std::size_t image_index = 0;
  const std::vector<Eigen::Isometry3d> truth = TruePoses(10.0, 30.0, &image_index);
  const Swathe true_swathe = MakeSwathe(truth, image_index);
  // The simulator's drift at its largest: 0.8 % scale, 0.03 deg/m about two axes across the travel.
  const Eigen::Matrix3d axes = MotionAxes(true_swathe.T_basek_basej);
  const double scale_error = 0.008;
  const double rate_a = RadiansFromDegrees(0.03), rate_b = RadiansFromDegrees(-0.02);
  const Eigen::Vector3d turn_rate = axes.col(0) * rate_a + axes.col(1) * rate_b;
  const Swathe drifted = MakeSwathe(Drifted(truth, scale_error, turn_rate), image_index);

  const auto [before_m, before_rad] = LargestDifference(drifted.T_basek_basej, true_swathe.T_basek_basej);
  // The drift is what the correction is for: 37 cm and 1.1 deg at 30 m.
  EXPECT_GT(before_m, 0.2);
  EXPECT_GT(before_rad, RadiansFromDegrees(0.8));

  // The correction that mirrors it, in the drifted swathe's own travel frame.
  const Eigen::Matrix3d drifted_axes = MotionAxes(drifted.T_basek_basej);
  SwatheMotionCorrection correction;
  correction.scale = 1.0 / (1.0 + scale_error) - 1.0;
  correction.turn_a_rad_per_m = -drifted_axes.col(0).dot(turn_rate) / (1.0 + scale_error);
  correction.turn_b_rad_per_m = -drifted_axes.col(1).dot(turn_rate) / (1.0 + scale_error);
  correction.roll_rad_per_m = -drifted_axes.col(2).dot(turn_rate) / (1.0 + scale_error);
  const std::vector<Eigen::Isometry3d> corrected =
      CorrectSwatheMotion(drifted.scan_t_us, drifted.T_basek_basej, drifted.image_t_us, correction);
  const auto [after_m, after_rad] = LargestDifference(corrected, true_swathe.T_basek_basej);
  std::cout << "[ measured ] drift over the swathe " << before_m * 100.0 << " cm, "
            << DegreesFromRadians(before_rad) << " deg; corrected " << after_m * 1000.0 << " mm, "
            << DegreesFromRadians(after_rad) << " deg\n";
  EXPECT_LT(after_m, 0.002);
  EXPECT_LT(after_rad, RadiansFromDegrees(0.002));

  // The opposite correction doubles the drift instead.
  SwatheMotionCorrection wrong = correction;
  wrong.turn_a_rad_per_m = -correction.turn_a_rad_per_m;
  wrong.turn_b_rad_per_m = -correction.turn_b_rad_per_m;
  const auto [wrong_m, wrong_rad] = LargestDifference(
      CorrectSwatheMotion(drifted.scan_t_us, drifted.T_basek_basej, drifted.image_t_us, wrong),
      true_swathe.T_basek_basej);
  EXPECT_GT(wrong_rad, 1.5 * before_rad);
  EXPECT_GT(wrong_m, after_m);
}

}  // namespace
}  // namespace scenecal
