// Trajectory lookup: poses at and between samples, the covered span, and the
// distance travelled along the samples.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "core/trajectory.hpp"

namespace scenecal {
namespace {

// A realistic epoch in microseconds, so the arithmetic sees large integers.
constexpr TimeUs kEpochUs = 1'400'000'000'000'000;

Eigen::Isometry3d Pose(double x, double y, double z, double yaw) {
  Vector6d tuple;
  tuple << x, y, z, 0.0, 0.0, yaw;
  return TransformFromTuple(tuple);
}

double MatrixDistance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

// Yaw of a pose whose rotation is about z only.
double YawOf(const Eigen::Isometry3d& pose) { return std::atan2(pose.linear()(1, 0), pose.linear()(0, 0)); }

// Non-uniform sample times; the base drives along x, turning about z.
Trajectory MakeDrive(std::vector<TimeUs>* times, std::vector<Eigen::Isometry3d>* poses) {
  *times = {kEpochUs, kEpochUs + 100'000, kEpochUs + 150'000, kEpochUs + 400'000, kEpochUs + 410'000};
  *poses = {Pose(0, 0, 0, 0.0), Pose(1.0, 0.5, 0.1, 0.2), Pose(1.5, 0.5, 0.1, 0.3), Pose(4.0, -1.0, 0.2, -0.4),
            Pose(4.1, -1.0, 0.2, -0.5)};
  return Trajectory(*times, *poses);
}

TEST(Trajectory, PoseAtSamplesIsTheSample) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  const Trajectory trajectory = MakeDrive(&times, &poses);
  ASSERT_EQ(trajectory.size(), times.size());
  EXPECT_FALSE(trajectory.empty());
  for (std::size_t i = 0; i < times.size(); ++i) {
    const auto pose = trajectory.PoseAt(times[i]);
    ASSERT_TRUE(pose.has_value()) << i;
    EXPECT_LT(MatrixDistance(*pose, poses[i]), 1e-12) << i;
  }
}

TEST(Trajectory, PoseBetweenSamplesIsLinearInTranslationAndAngle) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  const Trajectory trajectory = MakeDrive(&times, &poses);
  for (std::size_t i = 0; i + 1 < times.size(); ++i) {
    for (double fraction : {0.001, 0.25, 0.5, 0.9, 0.999}) {
      const TimeUs t = times[i] + static_cast<TimeUs>(std::llround(fraction * static_cast<double>(times[i + 1] - times[i])));
      const double alpha = static_cast<double>(t - times[i]) / static_cast<double>(times[i + 1] - times[i]);
      const auto pose = trajectory.PoseAt(t);
      ASSERT_TRUE(pose.has_value());
      const Eigen::Vector3d expected_translation =
          poses[i].translation() + alpha * (poses[i + 1].translation() - poses[i].translation());
      EXPECT_LT((pose->translation() - expected_translation).norm(), 1e-12) << i << " " << fraction;
      // Rotations about one axis: slerp is linear in the angle.
      const double expected_yaw = YawOf(poses[i]) + alpha * (YawOf(poses[i + 1]) - YawOf(poses[i]));
      EXPECT_NEAR(YawOf(*pose), expected_yaw, 1e-12) << i << " " << fraction;
      EXPECT_TRUE(IsRigid(pose->matrix(), 1e-12));
    }
  }
}

TEST(Trajectory, RotationTakesTheShortWayAcrossPi) {
  // Yaw 3.0 -> -3.0 is a turn of 0.283 rad through pi, not 6 rad through 0.
  const Trajectory trajectory({0, 1000}, {Pose(0, 0, 0, 3.0), Pose(0, 0, 0, -3.0)});
  const auto middle = trajectory.PoseAt(500);
  ASSERT_TRUE(middle.has_value());
  EXPECT_NEAR(std::abs(YawOf(*middle)), kPi, 1e-12);
}

TEST(Trajectory, NoPoseOutsideTheSpan) {
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> poses;
  const Trajectory trajectory = MakeDrive(&times, &poses);
  EXPECT_FALSE(trajectory.PoseAt(times.front() - 1).has_value());
  EXPECT_FALSE(trajectory.PoseAt(times.back() + 1).has_value());
  EXPECT_FALSE(trajectory.PoseAt(0).has_value());
  EXPECT_TRUE(trajectory.PoseAt(times.front()).has_value());
  EXPECT_TRUE(trajectory.PoseAt(times.back()).has_value());

  const Trajectory empty;
  EXPECT_TRUE(empty.empty());
  EXPECT_FALSE(empty.PoseAt(0).has_value());
  EXPECT_EQ(empty.DistanceAt(0), 0.0);
  EXPECT_EQ(empty.TotalDistance(), 0.0);
}

TEST(Trajectory, SingleRowHasAPoseOnlyAtItsTime) {
  const Eigen::Isometry3d pose = Pose(1, 2, 3, 0.7);
  const Trajectory trajectory({kEpochUs}, {pose});
  const auto at = trajectory.PoseAt(kEpochUs);
  ASSERT_TRUE(at.has_value());
  EXPECT_LT(MatrixDistance(*at, pose), 1e-15);
  EXPECT_FALSE(trajectory.PoseAt(kEpochUs - 1).has_value());
  EXPECT_FALSE(trajectory.PoseAt(kEpochUs + 1).has_value());
  EXPECT_EQ(trajectory.DistanceAt(kEpochUs), 0.0);
  EXPECT_EQ(trajectory.DistanceAt(kEpochUs + 1'000'000), 0.0);
  EXPECT_EQ(trajectory.TotalDistance(), 0.0);
}

TEST(Trajectory, DistanceIsAlongTheSamplesAndClamped) {
  // An L-shaped path: 3 m along x, then 4 m along y (7 m travelled, 5 m chord).
  const std::vector<TimeUs> times{kEpochUs, kEpochUs + 3'000'000, kEpochUs + 5'000'000};
  const Trajectory trajectory(times, {Pose(0, 0, 0, 0), Pose(3, 0, 0, 0.5), Pose(3, 4, 0, 1.0)});
  EXPECT_NEAR(trajectory.TotalDistance(), 7.0, 1e-12);
  EXPECT_NEAR(trajectory.DistanceAt(times[0]), 0.0, 1e-12);
  EXPECT_NEAR(trajectory.DistanceAt(times[1]), 3.0, 1e-12);
  EXPECT_NEAR(trajectory.DistanceAt(times[2]), 7.0, 1e-12);
  // Between samples: proportional to time within the segment.
  EXPECT_NEAR(trajectory.DistanceAt(kEpochUs + 1'000'000), 1.0, 1e-12);
  EXPECT_NEAR(trajectory.DistanceAt(kEpochUs + 4'500'000), 3.0 + 4.0 * 0.75, 1e-12);
  // Clamped to the covered span.
  EXPECT_EQ(trajectory.DistanceAt(kEpochUs - 5), 0.0);
  EXPECT_NEAR(trajectory.DistanceAt(kEpochUs + 9'000'000), 7.0, 1e-12);
  // Monotonic in time, and consistent with the interpolated positions on a
  // straight segment.
  double previous = -1.0;
  for (TimeUs t = kEpochUs; t <= times.back(); t += 250'000) {
    const double distance = trajectory.DistanceAt(t);
    EXPECT_GE(distance, previous);
    previous = distance;
    if (t <= times[1]) {
      EXPECT_NEAR(distance, trajectory.PoseAt(t)->translation().norm(), 1e-12);
    }
  }
}

TEST(Trajectory, StandingStillTravelsNothing) {
  const Eigen::Isometry3d pose = Pose(5, 5, 0, 0.1);
  const Trajectory trajectory({0, 10, 20}, {pose, pose, pose});
  EXPECT_EQ(trajectory.TotalDistance(), 0.0);
  EXPECT_EQ(trajectory.DistanceAt(15), 0.0);
  EXPECT_LT(MatrixDistance(*trajectory.PoseAt(15), pose), 1e-12);
}

}  // namespace
}  // namespace scenecal
