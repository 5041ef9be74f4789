#include "core/geometry.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/SVD>

namespace scenecal {

Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d RollPitchYawFromRotation(const Eigen::Matrix3d& r) {
  // R = Rz(y) Ry(p) Rx(r): r20 = -sin(p), r21 = cos(p) sin(r), r22 = cos(p) cos(r),
  // r10 = sin(y) cos(p), r00 = cos(y) cos(p).
  const double sin_pitch = std::clamp(-r(2, 0), -1.0, 1.0);
  const double cos_pitch = std::hypot(r(0, 0), r(1, 0));
  const double pitch = std::atan2(sin_pitch, cos_pitch);
  if (cos_pitch > 1e-9) {
    return {std::atan2(r(2, 1), r(2, 2)), pitch, std::atan2(r(1, 0), r(0, 0))};
  }
  // Gimbal lock: only roll - yaw (pitch = +pi/2) or roll + yaw (pitch = -pi/2)
  // is defined; take yaw = 0 and recover roll from the remaining entries.
  const double roll = sin_pitch > 0 ? std::atan2(r(0, 1), r(1, 1)) : std::atan2(-r(0, 1), r(1, 1));
  return {roll, pitch, 0.0};
}

Eigen::Isometry3d TransformFromTuple(const Vector6d& v) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = RotationFromRollPitchYaw(v[3], v[4], v[5]);
  t.translation() = v.head<3>();
  return t;
}

Vector6d TupleFromTransform(const Eigen::Isometry3d& t) {
  Vector6d v;
  v.head<3>() = t.translation();
  v.tail<3>() = RollPitchYawFromRotation(t.linear());
  return v;
}

Eigen::Isometry3d TransformFromQuaternion(const Eigen::Quaterniond& q, const Eigen::Vector3d& translation) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = q.normalized().toRotationMatrix();
  t.translation() = translation;
  return t;
}

namespace {
Eigen::Matrix3d Hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

// Left Jacobian V of SO(3): t = V * rho for the SE(3) exponential.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d w = Hat(phi);
  if (theta < 1e-5) return Eigen::Matrix3d::Identity() + 0.5 * w + w * w / 6.0;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * w +
         (theta - std::sin(theta)) / (t2 * theta) * w * w;
}
}  // namespace

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  if (theta < 1e-12) return Eigen::Matrix3d::Identity() + Hat(phi);
  return Eigen::AngleAxisd(theta, phi / theta).toRotationMatrix();
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& r) {
  // Quaternion route is stable near 0 and near pi.
  Eigen::Quaterniond q(r);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  const double vec_norm = q.vec().norm();
  if (vec_norm < 1e-12) return 2.0 * q.vec();
  const double theta = 2.0 * std::atan2(vec_norm, q.w());
  return theta / vec_norm * q.vec();
}

Eigen::Isometry3d ExpSE3(const Vector6d& twist) {
  const Eigen::Vector3d rho = twist.head<3>();
  const Eigen::Vector3d phi = twist.tail<3>();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = ExpSO3(phi);
  t.translation() = LeftJacobianSO3(phi) * rho;
  return t;
}

Vector6d LogSE3(const Eigen::Isometry3d& t) {
  const Eigen::Vector3d phi = LogSO3(t.linear());
  Vector6d twist;
  twist.head<3>() = LeftJacobianSO3(phi).inverse() * t.translation();
  twist.tail<3>() = phi;
  return twist;
}

Matrix6d AdjointSE3(const Eigen::Isometry3d& t) {
  const Eigen::Matrix3d R = t.linear();
  Matrix6d adjoint = Matrix6d::Zero();
  adjoint.topLeftCorner<3, 3>() = R;
  adjoint.topRightCorner<3, 3>() = Hat(t.translation()) * R;
  adjoint.bottomRightCorner<3, 3>() = R;
  return adjoint;
}

Vector6d DifferenceLog(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return LogSE3(a * b.inverse());
}

Vector6d DifferenceTuple(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return TupleFromTransform(a * b.inverse());
}

Eigen::Isometry3d Interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double alpha) {
  const Eigen::Quaterniond qa(a.linear());
  const Eigen::Quaterniond qb(b.linear());
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = qa.slerp(alpha, qb).toRotationMatrix();
  t.translation() = (1.0 - alpha) * a.translation() + alpha * b.translation();
  return t;
}

double TranslationError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& reference) {
  return (estimate.translation() - reference.translation()).norm();
}

double RotationErrorDegrees(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& reference) {
  return DegreesFromRadians(LogSO3(estimate.linear() * reference.linear().transpose()).norm());
}

bool IsRigid(const Eigen::Matrix4d& m, double tolerance) {
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if (!m.allFinite()) return false;
  if ((r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > tolerance) return false;
  if (std::abs(r.determinant() - 1.0) > tolerance) return false;
  const Eigen::RowVector4d last(0, 0, 0, 1);
  return (m.row(3) - last).cwiseAbs().maxCoeff() <= tolerance;
}

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& matrix) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(matrix, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

}  // namespace scenecal
