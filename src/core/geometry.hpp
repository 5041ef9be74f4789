// Rigid transforms in the project's conventions (FORMAT.md).
//
// A transform T_a_b maps coordinates of a point from frame b into frame a:
// p_a = T_a_b * p_b. The file form is the 6-tuple [x, y, z, roll, pitch, yaw]
// (metres, radians) with R = Rz(yaw) * Ry(pitch) * Rx(roll).
//
// Tangent ordering (as in Sophus): a twist is [rho; phi], translation-like part
// first (metres), rotation vector second (radians). ExpSE3/LogSE3 use it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scenecal {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// R = Rz(yaw) * Ry(pitch) * Rx(roll); angles in radians.
Eigen::Matrix3d RotationFromRollPitchYaw(double roll, double pitch, double yaw);
// Inverse of RotationFromRollPitchYaw; pitch in [-pi/2, pi/2], roll and yaw in
// (-pi, pi]. At pitch = +-pi/2 (gimbal lock) yaw is set to 0 and roll absorbs
// the remaining rotation, so the round trip through the matrix is exact.
Eigen::Vector3d RollPitchYawFromRotation(const Eigen::Matrix3d& rotation);

// [x, y, z, roll, pitch, yaw] <-> transform.
Eigen::Isometry3d TransformFromTuple(const Vector6d& xyz_rpy);
Vector6d TupleFromTransform(const Eigen::Isometry3d& transform);

// Unit quaternion (any sign) and translation -> transform.
Eigen::Isometry3d TransformFromQuaternion(const Eigen::Quaterniond& rotation,
                                          const Eigen::Vector3d& translation);

// SO(3) and SE(3) exponential and logarithm; tangent ordering [rho; phi].
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& rotation_vector);
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& rotation);
Eigen::Isometry3d ExpSE3(const Vector6d& twist);
Vector6d LogSE3(const Eigen::Isometry3d& transform);
// Adjoint of T for [rho; phi] twists: T * Exp(xi) * T^-1 = Exp(AdjointSE3(T) * xi),
// i.e. a twist in T's source frame expressed in its target frame.
Matrix6d AdjointSE3(const Eigen::Isometry3d& transform);

// The paper's difference A (-) B = A * B^-1, as a 6-vector. The project uses
// the SE(3) logarithm for penalties (smooth everywhere); the 6-tuple form is
// given for reports in the paper's parameterisation.
Vector6d DifferenceLog(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);
Vector6d DifferenceTuple(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

// Interpolation between poses a (alpha = 0) and b (alpha = 1): linear in
// translation, slerp in rotation.
Eigen::Isometry3d Interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                              double alpha);

// Errors of an estimate against a reference, as FORMAT.md defines them:
// |t_est - t_ref| in metres, and the angle of R_est * R_ref^T in degrees.
double TranslationError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& reference);
double RotationErrorDegrees(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& reference);

// True when the linear part is a rotation within tolerance (orthonormal, det +1).
bool IsRigid(const Eigen::Matrix4d& matrix, double tolerance = 1e-6);

// The rotation nearest (Frobenius) to a matrix that is one up to printing
// precision (check IsRigid first): U V^T of its SVD.
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& matrix);

constexpr double kPi = 3.14159265358979323846;
constexpr double DegreesFromRadians(double radians) { return radians * 180.0 / kPi; }
constexpr double RadiansFromDegrees(double degrees) { return degrees * kPi / 180.0; }

}  // namespace scenecal
