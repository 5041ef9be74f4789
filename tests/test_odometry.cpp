// Lidar odometry: a synthetic street with traffic moving beside the car, the
// drift measure, and the `odometry` command on the real DGP scene.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/geometry.hpp"
#include "io/dataset.hpp"
#include "io/dgp.hpp"
#include "io_test_support.hpp"
#include "odometry/lidar_odometry.hpp"

namespace scenecal {
namespace {

using namespace scenecal::testing;

constexpr TimeUs kScanPeriodUs = 100'000;  // 10 Hz

// A street in world coordinates (z up): the road, two house fronts with
// window recesses, poles along the kerbs and a few parked boxes.
std::vector<Eigen::Vector3d> StaticStreet() {
  std::vector<Eigen::Vector3d> points;
  const double step = 0.3;
  for (double x = -20; x <= 95; x += step) {
    for (double y = -7; y <= 7; y += 2 * step) points.emplace_back(x, y, 0.002 * std::sin(x));
    for (const double side : {-8.0, 8.0}) {
      for (double z = 0; z <= 8; z += step) {
        // Windows 0.3 m deep every 6 m: structure along the street.
        const bool window = std::fmod(x + 100.0, 6.0) < 2.0 && z > 2 && z < 4;
        points.emplace_back(x, side + (window ? std::copysign(0.3, side) : 0.0), z);
      }
    }
  }
  for (double x = -15; x <= 95; x += 9) {  // poles
    for (double z = 0; z <= 4; z += step) {
      for (int a = 0; a < 8; ++a) {
        const double angle = a * kPi / 4;
        points.emplace_back(x + 0.15 * std::cos(angle), 6.0 + 0.15 * std::sin(angle), z);
      }
    }
  }
  for (double x0 = 5; x0 <= 90; x0 += 23) {  // parked cars: boxes 4 x 1.8 x 1.5 m
    for (double x = x0; x <= x0 + 4; x += step) {
      for (double z = 0; z <= 1.5; z += step) points.emplace_back(x, -5.0, z);
    }
  }
  return points;
}

// A truck's side, 10 m long, 3 m high, beside the car at `x` (world).
std::vector<Eigen::Vector3d> Truck(double x) {
  std::vector<Eigen::Vector3d> points;
  for (double dx = 0; dx <= 10; dx += 0.2) {
    for (double z = 0.3; z <= 3.3; z += 0.2) points.emplace_back(x + dx, 3.0, z);
  }
  return points;
}

// The vehicle drives along x at 8 m/s with a gentle weave; the lidar sits 1.8 m up.
Eigen::Isometry3d TrueLidarPose(int scan) {
  const double t = 0.1 * scan;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  const double heading = 0.03 * std::sin(0.4 * t);
  pose.linear() = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(8.0 * t, 0.5 * std::sin(0.2 * t), 1.8);
  return pose;
}

LidarScan SeeStreet(const std::vector<Eigen::Vector3d>& world, const Eigen::Isometry3d& T_world_lidar, TimeUs t_us,
                    std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, 0.01);
  LidarScan scan;
  scan.t_us = t_us;
  const Eigen::Isometry3d T_lidar_world = T_world_lidar.inverse();
  for (const Eigen::Vector3d& p : world) {
    const Eigen::Vector3d q = T_lidar_world * p;
    if (q.norm() > 40.0) continue;
    scan.points.push_back({static_cast<float>(q.x() + noise(rng)), static_cast<float>(q.y() + noise(rng)),
                           static_cast<float>(q.z() + noise(rng)), 1.0f});
  }
  return scan;
}

// A truck passes the car (12 m/s against the car's 8) a metre and a half to
// its left for the whole drive: a frame-to-frame registration would take part
// of its motion for the car's.
TEST(LidarOdometry, StreetWithPassingTruckDriftsLittle) {
  const std::vector<Eigen::Vector3d> street = StaticStreet();
  std::mt19937 rng(7);
  odometry::LidarOdometry estimator({});
  constexpr int kScans = 60;  // 48 m
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> truth;
  for (int i = 0; i < kScans; ++i) {
    std::vector<Eigen::Vector3d> world = street;
    const std::vector<Eigen::Vector3d> truck = Truck(-4.0 + 1.2 * i);
    world.insert(world.end(), truck.begin(), truck.end());
    const TimeUs t_us = kScanPeriodUs * i;
    estimator.Add(SeeStreet(world, TrueLidarPose(i), t_us, rng));
    times.push_back(t_us);
    truth.push_back(TrueLidarPose(0).inverse() * TrueLidarPose(i));
  }
  std::vector<Eigen::Isometry3d> estimated;
  std::size_t weak = 0;
  for (const odometry::OdometryStep& step : estimator.steps()) {
    estimated.push_back(step.T_world_lidar);
    weak += step.weak;
  }
  EXPECT_EQ(weak, 0u);
  const odometry::DriftStatistics drift = odometry::CompareWithReference(times, estimated, Trajectory(times, truth), 20.0);
  EXPECT_NEAR(drift.distance_m, 47.3, 0.5);
  ASSERT_GT(drift.segments, 30u);
  EXPECT_LT(drift.segment_translation_percent, 1.0);
  // The local map measured 0.2 cm at the end and 0.0002 deg/m; registered
  // frame to frame (one keyframe, every scan) the same scans end 2.1 cm off
  // and drift 0.002 deg/m, failing these two.
  EXPECT_LT(drift.segment_rotation_deg_per_m, 0.001);
  EXPECT_LT(drift.end_translation_m, 0.01);
}

TEST(LidarOdometry, DriftOfAKnownScaleError) {
  // An odometry 2 % long on a straight line, rolling at a constant rate about
  // the direction of travel (which leaves the relative translations alone).
  std::vector<TimeUs> times;
  std::vector<Eigen::Isometry3d> reference, estimated;
  for (int i = 0; i <= 200; ++i) {
    times.push_back(kScanPeriodUs * i);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(1.0 * i, 0, 0);
    reference.push_back(pose);
    pose.translation() *= 1.02;
    pose.linear() = Eigen::AngleAxisd(RadiansFromDegrees(0.005 * i), Eigen::Vector3d::UnitX()).toRotationMatrix();
    estimated.push_back(pose);
  }
  const odometry::DriftStatistics drift =
      odometry::CompareWithReference(times, estimated, Trajectory(times, reference), 100.0);
  EXPECT_EQ(drift.compared, 201u);
  EXPECT_NEAR(drift.distance_m, 200.0, 1e-9);
  EXPECT_EQ(drift.segments, 101u);  // starts 0..100, each 100 m long
  EXPECT_NEAR(drift.segment_translation_percent, 2.0, 1e-6);
  EXPECT_NEAR(drift.segment_rotation_deg_per_m, 0.005, 1e-9);
  EXPECT_NEAR(drift.end_rotation_deg, 1.0, 1e-9);
}

TEST(LidarOdometry, RefusesBadOptionsAndTimesOutOfOrder) {
  odometry::LidarOdometryOptions options;
  options.voxel_m = 0.0;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("voxel_m"), std::string::npos);
  EXPECT_THROW(odometry::LidarOdometry{options}, std::invalid_argument);
  odometry::LidarOdometry estimator({});
  LidarScan scan;
  scan.t_us = 10;
  estimator.Add(scan);
  EXPECT_TRUE(estimator.steps().back().weak);  // no points: nothing to register
  EXPECT_THROW(estimator.Add(scan), std::invalid_argument);
}

TEST(LidarOdometry, CommandOnTheDgpScene) {
  const fs::path scene = fs::path(SCENECAL_SHARED_DATA_DIR) / "dgp" / "scene_01";
  ASSERT_TRUE(fs::exists(scene)) << scene;
  const TempDir temp;
  const fs::path dataset = temp.path() / "dgp";
  io::ImportDgp(scene, dataset, {});
  const fs::path output = temp.path() / "odometry.csv";
  const CliRun run = RunCli("odometry '" + dataset.string() + "' --lidar LIDAR --output '" + output.string() + "'",
                            temp.path());
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("against"), std::string::npos) << run.stderr_text;
  // The vehicle stands: the odometry's poses agree with the recorded ones.
  const Trajectory estimated = io::ReadTrajectory(output);
  const Trajectory recorded = io::ReadTrajectory(dataset / "trajectory.csv");
  ASSERT_EQ(estimated.size(), 3u);
  const Eigen::Isometry3d recorded_first = *recorded.PoseAt(estimated.times_us().front());
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    const Eigen::Isometry3d recorded_motion = recorded_first.inverse() * *recorded.PoseAt(estimated.times_us()[i]);
    const Eigen::Isometry3d estimated_motion = estimated.poses().front().inverse() * estimated.poses()[i];
    EXPECT_LT(TranslationError(estimated_motion, recorded_motion), 0.02);
    EXPECT_LT(RotationErrorDegrees(estimated_motion, recorded_motion), 0.05);
  }
  // The extrinsic from ground_truth.yaml, or a missing result file refused before any work.
  const CliRun truth = RunCli("odometry '" + dataset.string() + "' --lidar LIDAR --extrinsic truth --output '" +
                                  (temp.path() / "truth.csv").string() + "'",
                              temp.path());
  EXPECT_EQ(truth.exit_code, 0) << truth.stderr_text;
  const CliRun missing = RunCli("odometry '" + dataset.string() + "' --lidar LIDAR --extrinsic '" +
                                    (temp.path() / "none.yaml").string() + "' --output '" +
                                    (temp.path() / "none.csv").string() + "'",
                                temp.path());
  EXPECT_EQ(missing.exit_code, 2) << missing.stderr_text;
  EXPECT_EQ(missing.stderr_text.find("registered"), std::string::npos) << "ran before checking: " << missing.stderr_text;
  EXPECT_FALSE(fs::exists(temp.path() / "none.csv"));
  // An existing trajectory is not replaced without --force; a 2d lidar is refused.
  const CliRun again = RunCli("odometry '" + dataset.string() + "' --lidar LIDAR --output '" + output.string() + "'",
                              temp.path());
  EXPECT_EQ(again.exit_code, 2) << again.stderr_text;
  EXPECT_NE(again.stderr_text.find("--force"), std::string::npos) << again.stderr_text;
  EXPECT_TRUE(ReplaceInFile(dataset / "rig.yaml", "kind: 3d", "kind: 2d"));
  const CliRun flat = RunCli("odometry '" + dataset.string() + "' --lidar LIDAR --output '" +
                                 (temp.path() / "b.csv").string() + "'",
                             temp.path());
  EXPECT_EQ(flat.exit_code, 2) << flat.stderr_text;
  EXPECT_NE(flat.stderr_text.find("3d lidar"), std::string::npos) << flat.stderr_text;
  EXPECT_FALSE(fs::exists(temp.path() / "b.csv"));
}

}  // namespace
}  // namespace scenecal
