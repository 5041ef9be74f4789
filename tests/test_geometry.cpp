// Property tests of SE(3) in the project's conventions.
#include <random>

#include <gtest/gtest.h>

#include "core/geometry.hpp"

namespace scenecal {
namespace {

Vector6d RandomTuple(std::mt19937& rng, double max_pitch = 1.5) {
  std::uniform_real_distribution<double> t(-5.0, 5.0);
  std::uniform_real_distribution<double> a(-3.1, 3.1);
  std::uniform_real_distribution<double> p(-max_pitch, max_pitch);
  Vector6d v;
  v << t(rng), t(rng), t(rng), a(rng), p(rng), a(rng);
  return v;
}

double MatrixDistance(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

TEST(Geometry, RollPitchYawMatchesRobotCarConvention) {
  // R = Rz(yaw) Ry(pitch) Rx(roll), checked entry by entry for a 90 deg yaw:
  // x maps to y.
  const Eigen::Matrix3d r = RotationFromRollPitchYaw(0, 0, kPi / 2);
  EXPECT_NEAR((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);
  // Order: roll first (about x), then pitch, then yaw.
  const double roll = 0.3, pitch = -0.2, yaw = 0.7;
  const Eigen::Matrix3d expected = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_LT((RotationFromRollPitchYaw(roll, pitch, yaw) - expected).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Geometry, TupleRoundTrip) {
  std::mt19937 rng(1);
  for (int i = 0; i < 2000; ++i) {
    const Vector6d v = RandomTuple(rng);
    const Vector6d back = TupleFromTransform(TransformFromTuple(v));
    EXPECT_LT((back - v).cwiseAbs().maxCoeff(), 1e-9) << v.transpose();
  }
}

TEST(Geometry, NearSingularPitchRoundTripsThroughTheMatrix) {
  // The RobotCar lidars sit at pitch -1.51 rad; test up to and at +-90 deg.
  const Vector6d lms_rear = (Vector6d() << -2.5850, 0.2852, 1.0885, -2.8405, -1.5090, -0.3614).finished();
  EXPECT_LT((TupleFromTransform(TransformFromTuple(lms_rear)) - lms_rear).cwiseAbs().maxCoeff(), 1e-9);
  std::mt19937 rng(2);
  for (double pitch : {kPi / 2, -kPi / 2, kPi / 2 - 1e-7, -kPi / 2 + 1e-9, 1.5707, -1.51}) {
    for (int i = 0; i < 200; ++i) {
      Vector6d v = RandomTuple(rng);
      v[4] = pitch;
      const Eigen::Isometry3d t = TransformFromTuple(v);
      const Vector6d back = TupleFromTransform(t);
      EXPECT_TRUE(back.allFinite());
      EXPECT_LT(MatrixDistance(TransformFromTuple(back), t), 1e-6) << v.transpose();
      EXPECT_NEAR(back[4], pitch, 1e-3);
    }
  }
}

TEST(Geometry, ExpLogRoundTrip) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    Vector6d twist;
    for (int k = 0; k < 6; ++k) twist[k] = n(rng);
    if (twist.tail<3>().norm() > 3.0) twist.tail<3>() *= 3.0 / twist.tail<3>().norm();
    if (i % 10 == 0) twist.tail<3>() *= 1e-9;  // the small-angle branch
    EXPECT_LT((LogSE3(ExpSE3(twist)) - twist).cwiseAbs().maxCoeff(), 1e-8) << twist.transpose();
  }
  // Near pi the logarithm stays finite and the exponential reproduces the rotation.
  const Eigen::Isometry3d half_turn = TransformFromTuple((Vector6d() << 1, 2, 3, kPi - 1e-9, 0, 0).finished());
  EXPECT_LT(MatrixDistance(ExpSE3(LogSE3(half_turn)), half_turn), 1e-8);
}

TEST(Geometry, AdjointMovesATwistBetweenFrames) {
  const Eigen::Isometry3d T = TransformFromTuple((Vector6d() << 0.3, -1.2, 4.1, 0.4, -1.1, 2.0).finished());
  const Vector6d twist = (Vector6d() << 0.02, -0.01, 0.03, 0.004, 0.006, -0.002).finished();
  const Eigen::Isometry3d conjugated = T * ExpSE3(twist) * T.inverse();
  const Eigen::Isometry3d moved = ExpSE3(AdjointSE3(T) * twist);
  EXPECT_LT((conjugated.matrix() - moved.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((AdjointSE3(T.inverse()) * AdjointSE3(T) - Matrix6d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  // A turn about the source frame's origin is a turn plus a lever-arm shift in the target frame.
  const Vector6d turn = (Vector6d() << 0, 0, 0, 0.001, 0, 0).finished();
  EXPECT_NEAR((AdjointSE3(T) * turn).head<3>().norm(), 0.001 * T.translation().cross(T.linear().col(0)).norm(), 1e-12);
}

TEST(Geometry, GroupLaws) {
  std::mt19937 rng(4);
  for (int i = 0; i < 500; ++i) {
    const Eigen::Isometry3d a = TransformFromTuple(RandomTuple(rng));
    const Eigen::Isometry3d b = TransformFromTuple(RandomTuple(rng));
    const Eigen::Isometry3d c = TransformFromTuple(RandomTuple(rng));
    EXPECT_LT(MatrixDistance((a * b) * c, a * (b * c)), 1e-12);
    EXPECT_LT(MatrixDistance(a * a.inverse(), Eigen::Isometry3d::Identity()), 1e-12);
    // A (-) B = A * B^-1, so (A (-) B) * B = A.
    EXPECT_LT(MatrixDistance(ExpSE3(DifferenceLog(a, b)) * b, a), 1e-8);
    EXPECT_LT(MatrixDistance(TransformFromTuple(DifferenceTuple(a, b)) * b, a), 1e-8);
    EXPECT_LT(DifferenceLog(a, a).norm(), 1e-12);
  }
}

TEST(Geometry, InterpolationEndsAndMidpoint) {
  std::mt19937 rng(5);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Isometry3d a = TransformFromTuple(RandomTuple(rng));
    const Eigen::Isometry3d b = TransformFromTuple(RandomTuple(rng));
    EXPECT_LT(MatrixDistance(Interpolate(a, b, 0.0), a), 1e-12);
    EXPECT_LT(MatrixDistance(Interpolate(a, b, 1.0), b), 1e-9);
    const Eigen::Isometry3d mid = Interpolate(a, b, 0.5);
    EXPECT_NEAR(RotationErrorDegrees(mid, a), RotationErrorDegrees(b, mid), 1e-6);
    EXPECT_LT((mid.translation() - 0.5 * (a.translation() + b.translation())).norm(), 1e-12);
  }
}

TEST(Geometry, ErrorsAsFormatDefinesThem) {
  const Eigen::Isometry3d ref = TransformFromTuple((Vector6d() << 1, 2, 3, 0.1, 0.2, 0.3).finished());
  Eigen::Isometry3d est = ref;
  est.translation() += Eigen::Vector3d(0.03, 0.04, 0.0);
  EXPECT_NEAR(TranslationError(est, ref), 0.05, 1e-12);
  est.linear() = Eigen::AngleAxisd(RadiansFromDegrees(0.5), Eigen::Vector3d(1, 1, 0).normalized()) * ref.linear();
  EXPECT_NEAR(RotationErrorDegrees(est, ref), 0.5, 1e-9);
}

TEST(Geometry, IsRigidRejectsNonRotations) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  EXPECT_TRUE(IsRigid(m));
  m(0, 0) = -1;  // a reflection
  EXPECT_FALSE(IsRigid(m));
  m = Eigen::Matrix4d::Identity();
  m(0, 1) = 0.01;
  EXPECT_FALSE(IsRigid(m));
  m = Eigen::Matrix4d::Identity();
  m(3, 0) = 1;
  EXPECT_FALSE(IsRigid(m));
}

}  // namespace
}  // namespace scenecal
