#include "core/camera.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/LU>

#include "core/camera_kernel.hpp"
#include "core/geometry.hpp"
#include "core/validation.hpp"

namespace scenecal {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kHalfPi = kPi / 2.0;

// Polynomial sum_i c[i] s^i, coefficients in ascending order.
using Polynomial = std::vector<double>;

double Evaluate(const Polynomial& c, double s) {
  double value = 0.0;
  for (auto it = c.rbegin(); it != c.rend(); ++it) value = value * s + *it;
  return value;
}

Polynomial Derivative(const Polynomial& c) {
  Polynomial d;
  for (std::size_t i = 1; i < c.size(); ++i) d.push_back(static_cast<double>(i) * c[i]);
  return d;
}

// Root of c in [a, b] when c(a) and c(b) have opposite signs (or c(b) == 0).
double Bisect(const Polynomial& c, double a, double b) {
  const bool a_negative = Evaluate(c, a) < 0.0;
  for (int i = 0; i < 2000; ++i) {
    const double mid = 0.5 * (a + b);
    if (mid <= a || mid >= b) break;  // interval exhausted in double precision
    if ((Evaluate(c, mid) < 0.0) == a_negative) {
      a = mid;
    } else {
      b = mid;
    }
  }
  return b;
}

// Real roots of c in (lo, hi], ascending. Between consecutive roots of the
// derivative (found recursively) c is monotonic, so each piece holds at most
// one root, found by bisection. A root touching zero without a sign change at
// a critical point is reported too.
std::vector<double> RealRootsIn(Polynomial c, double lo, double hi) {
  while (!c.empty() && c.back() == 0.0) c.pop_back();
  std::vector<double> roots;
  if (c.size() <= 1) return roots;  // constant
  if (c.size() == 2) {
    const double root = -c[0] / c[1];
    if (root > lo && root <= hi) roots.push_back(root);
    return roots;
  }
  std::vector<double> knots{lo};
  for (double critical : RealRootsIn(Derivative(c), lo, hi)) {
    if (critical > knots.back() && critical < hi) knots.push_back(critical);
  }
  knots.push_back(hi);
  for (std::size_t i = 0; i + 1 < knots.size(); ++i) {
    const double fa = Evaluate(c, knots[i]);
    const double fb = Evaluate(c, knots[i + 1]);
    if (fb == 0.0) {
      roots.push_back(knots[i + 1]);
    } else if (fa != 0.0 && (fa < 0.0) != (fb < 0.0)) {
      roots.push_back(Bisect(c, knots[i], knots[i + 1]));
    }
  }
  return roots;
}

// Smallest s > 0 with g(s) <= 0 for g(0) = 1, searched in (0, hi]; when the
// leading coefficient is negative g becomes negative somewhere past hi too, so
// the search continues outward (radtan has no natural upper bound).
double FirstNonPositive(const Polynomial& g, double hi, bool unbounded) {
  const std::vector<double> roots = RealRootsIn(g, 0.0, hi);
  if (!roots.empty()) return roots.front();
  if (!unbounded) return kInfinity;
  Polynomial trimmed = g;
  while (!trimmed.empty() && trimmed.back() == 0.0) trimmed.pop_back();
  if (trimmed.empty() || trimmed.back() > 0.0) return kInfinity;
  double lo = hi;
  double far = hi;
  while (Evaluate(trimmed, far) > 0.0 && far < 1e300) {
    lo = far;
    far *= 4.0;
  }
  return Evaluate(trimmed, far) > 0.0 ? kInfinity : Bisect(trimmed, lo, far);
}

// Distortion coefficients padded to 5 (radtan k3 = 0 when absent).
std::array<double, 5> PaddedCoefficients(const CameraModel& camera) {
  std::array<double, 5> k{0, 0, 0, 0, 0};
  const std::size_t n = std::min<std::size_t>(camera.distortion.size(), 5);
  for (std::size_t i = 0; i < n; ++i) k[i] = camera.distortion[i];
  return k;
}

// Project calls this per point; computing the limit is a root search, so keep
// the last camera's answer per thread (models rarely change within a loop).
double CachedMonotonicLimit(const CameraModel& camera) {
  struct Entry {
    CameraModelKind kind = CameraModelKind::kPinhole;
    std::array<double, 5> k{};
    std::size_t size = 0;
    double limit = kInfinity;
    bool filled = false;
  };
  thread_local Entry cache;
  const std::array<double, 5> k = PaddedCoefficients(camera);
  if (!cache.filled || cache.kind != camera.kind || cache.k != k ||
      cache.size != camera.distortion.size()) {
    cache.kind = camera.kind;
    cache.k = k;
    cache.size = camera.distortion.size();
    cache.limit = camera.MonotonicDistortionLimitSquared();
    cache.filled = true;
  }
  return cache.limit;
}

// Inverse of the radtan distortion: the normalised point whose distortion is
// `target`, by Newton's method with step halving, kept inside the monotonic
// range (s < limit) so it cannot converge to a folded-over solution.
Eigen::Vector2d UndistortRadTan(const std::array<double, 5>& k, const Eigen::Vector2d& target,
                                double limit) {
  const auto residual_at = [&](const Eigen::Vector2d& p) {
    Eigen::Vector2d distorted;
    camera_detail::DistortRadTan(k.data(), p.x(), p.y(), &distorted.x(), &distorted.y());
    return Eigen::Vector2d(distorted - target);
  };
  Eigen::Vector2d p = target;
  if (p.squaredNorm() >= limit) p *= std::sqrt(0.5 * limit) / p.norm();
  Eigen::Vector2d residual = residual_at(p);
  for (int iteration = 0; iteration < 100 && residual.norm() > 0.0; ++iteration) {
    const double x = p.x(), y = p.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
    const double radial_d_r2 = k[0] + r2 * (2.0 * k[1] + 3.0 * r2 * k[4]);
    Eigen::Matrix2d jacobian;
    jacobian(0, 0) = radial + 2.0 * x * x * radial_d_r2 + 2.0 * k[2] * y + 6.0 * k[3] * x;
    jacobian(0, 1) = 2.0 * x * y * radial_d_r2 + 2.0 * k[2] * x + 2.0 * k[3] * y;
    jacobian(1, 0) = jacobian(0, 1);
    jacobian(1, 1) = radial + 2.0 * y * y * radial_d_r2 + 6.0 * k[2] * y + 2.0 * k[3] * x;
    Eigen::Vector2d step = -jacobian.partialPivLu().solve(residual);
    if (!step.allFinite()) break;
    bool improved = false;
    for (int halving = 0; halving < 60; ++halving, step *= 0.5) {
      const Eigen::Vector2d candidate = p + step;
      if (candidate.squaredNorm() >= limit) continue;
      const Eigen::Vector2d candidate_residual = residual_at(candidate);
      if (candidate_residual.norm() < residual.norm()) {
        p = candidate;
        residual = candidate_residual;
        improved = true;
        break;
      }
    }
    if (!improved) break;  // at machine precision (or the pixel is unreachable)
  }
  return p;
}

// Inverse of the equidistant distortion in the angle: theta with
// theta_d(theta) = theta_distorted, by Newton's method safeguarded with a
// bracket [0, theta_max] on which theta_d is increasing.
double UndistortEquidistantAngle(const std::array<double, 5>& k, double theta_distorted,
                                 double theta_max) {
  const auto f = [&](double theta) {
    const double t2 = theta * theta;
    return theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))) - theta_distorted;
  };
  const auto f_prime = [&](double theta) {
    const double t2 = theta * theta;
    return 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
  };
  double lo = 0.0, hi = theta_max;
  if (f(hi) <= 0.0) return hi;  // beyond the reachable range
  double theta = std::min(theta_distorted, 0.5 * (lo + hi));
  for (int iteration = 0; iteration < 200; ++iteration) {
    const double value = f(theta);
    if (value == 0.0) break;
    if (value < 0.0) {
      lo = theta;
    } else {
      hi = theta;
    }
    double next = theta - value / f_prime(theta);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - theta) <= 1e-17 * std::max(1.0, theta) || next == theta) {
      theta = next;
      break;
    }
    theta = next;
  }
  return theta;
}

}  // namespace

bool ParseCameraModelKind(const std::string& name, CameraModelKind* kind) {
  return ParseEnumName(kCameraModelKindNames, name, kind);
}

const char* CameraModelKindName(CameraModelKind kind) { return EnumName(kCameraModelKindNames, kind); }

bool CameraModel::IsValid(std::string* why) const {
  std::ostringstream problem;
  if (width <= 0 || height <= 0) {
    problem << "image size must be positive, got " << width << "x" << height;
  } else if (!std::isfinite(fx) || !std::isfinite(fy) || fx <= 0.0 || fy <= 0.0) {
    problem << "focal lengths must be finite and positive, got fx=" << fx << " fy=" << fy;
  } else if (!std::isfinite(cx) || !std::isfinite(cy)) {
    problem << "principal point must be finite, got cx=" << cx << " cy=" << cy;
  } else {
    const std::size_t n = distortion.size();
    switch (kind) {
      case CameraModelKind::kPinhole:
        if (n != 0) problem << "pinhole takes no distortion coefficients, got " << n;
        break;
      case CameraModelKind::kRadTan:
        if (n != 4 && n != 5) problem << "radtan takes 4 or 5 distortion coefficients (k1 k2 p1 p2 [k3]), got " << n;
        break;
      case CameraModelKind::kEquidistant:
        if (n != 4) problem << "equidistant takes 4 distortion coefficients (k1 k2 k3 k4), got " << n;
        break;
    }
    if (problem.tellp() == 0) {
      for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(distortion[i])) {
          problem << "distortion coefficient " << i << " is not finite (" << distortion[i] << ")";
          break;
        }
      }
    }
  }
  if (problem.tellp() == 0) return true;
  return Invalid(why, problem.str());
}

double CameraModel::MonotonicDistortionLimitSquared() const {
  const std::array<double, 5> k = PaddedCoefficients(*this);
  switch (kind) {
    case CameraModelKind::kPinhole:
      return kInfinity;
    case CameraModelKind::kRadTan: {
      // d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] as a polynomial in s = r^2.
      const Polynomial g{1.0, 3.0 * k[0], 5.0 * k[1], 7.0 * k[4]};
      return FirstNonPositive(g, 1e8, /*unbounded=*/true);
    }
    case CameraModelKind::kEquidistant: {
      // d/dtheta [theta (1 + k1 t^2 + ... + k4 t^8)] in s = theta^2, theta < pi/2.
      const Polynomial g{1.0, 3.0 * k[0], 5.0 * k[1], 7.0 * k[2], 9.0 * k[3]};
      return std::min(kHalfPi * kHalfPi, FirstNonPositive(g, kHalfPi * kHalfPi, /*unbounded=*/false));
    }
  }
  return kInfinity;
}

Eigen::Vector2d CameraModel::DistortAndScale(const Eigen::Vector2d& normalised) const {
  double x = normalised.x();
  double y = normalised.y();
  switch (kind) {
    case CameraModelKind::kPinhole:
      break;
    case CameraModelKind::kRadTan: {
      const std::array<double, 5> k = PaddedCoefficients(*this);
      camera_detail::DistortRadTan(k.data(), x, y, &x, &y);
      break;
    }
    case CameraModelKind::kEquidistant: {
      const std::array<double, 5> k = PaddedCoefficients(*this);
      const double r = std::hypot(x, y);
      const double scale = camera_detail::EquidistantScale(k.data(), r, std::atan(r));
      x *= scale;
      y *= scale;
      break;
    }
  }
  return {fx * x + cx, fy * y + cy};
}

bool CameraModel::Project(const Eigen::Vector3d& p_camera, Eigen::Vector2d* pixel, double margin_px,
                          double min_depth) const {
  if (!(p_camera.z() > min_depth)) return false;
  const Eigen::Vector2d normalised = p_camera.head<2>() / p_camera.z();
  *pixel = DistortAndScale(normalised);
  const double u = pixel->x();
  const double v = pixel->y();
  if (!(u >= -0.5 + margin_px && u < width - 0.5 - margin_px && v >= -0.5 + margin_px &&
        v < height - 0.5 - margin_px)) {
    return false;
  }
  switch (kind) {
    case CameraModelKind::kPinhole:
      return true;
    case CameraModelKind::kRadTan:
      return normalised.squaredNorm() < CachedMonotonicLimit(*this);
    case CameraModelKind::kEquidistant: {
      const double theta = std::atan(normalised.norm());
      return theta * theta < CachedMonotonicLimit(*this);
    }
  }
  return false;
}

Eigen::Vector3d CameraModel::Unproject(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  switch (kind) {
    case CameraModelKind::kPinhole:
      return distorted.homogeneous();
    case CameraModelKind::kRadTan:
      return UndistortRadTan(PaddedCoefficients(*this), distorted, MonotonicDistortionLimitSquared())
          .homogeneous();
    case CameraModelKind::kEquidistant: {
      const double theta_distorted = distorted.norm();
      if (theta_distorted == 0.0) return Eigen::Vector3d::UnitZ();
      // Stay short of pi/2, where the ray would have no finite z = 1 form.
      const double theta_max = std::min(std::sqrt(MonotonicDistortionLimitSquared()), kHalfPi - 1e-9);
      const double theta = UndistortEquidistantAngle(PaddedCoefficients(*this), theta_distorted, theta_max);
      return (distorted * (std::tan(theta) / theta_distorted)).homogeneous();
    }
  }
  return distorted.homogeneous();
}

ProjectionParams MakeProjectionParams(const CameraModel& camera, double margin_px, double min_depth) {
  ProjectionParams params;
  params.fx = static_cast<float>(camera.fx);
  params.fy = static_cast<float>(camera.fy);
  params.cx = static_cast<float>(camera.cx);
  params.cy = static_cast<float>(camera.cy);
  const std::array<double, 5> k = PaddedCoefficients(camera);
  for (std::size_t i = 0; i < k.size(); ++i) params.k[i] = static_cast<float>(k[i]);
  params.kind = camera.kind;
  params.width = camera.width;
  params.height = camera.height;
  params.u_min = static_cast<float>(-0.5 + margin_px);
  params.u_max = static_cast<float>(camera.width - 0.5 - margin_px);
  params.v_min = static_cast<float>(-0.5 + margin_px);
  params.v_max = static_cast<float>(camera.height - 0.5 - margin_px);
  params.min_depth = static_cast<float>(min_depth);
  params.monotonic_limit_squared = static_cast<float>(camera.MonotonicDistortionLimitSquared());
  return params;
}

}  // namespace scenecal
