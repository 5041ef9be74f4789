// Allocation-free, inline projection for hot loops (cost kernels): a flat POD
// copy of a CameraModel in float and ProjectFast, which gives the same answer
// as CameraModel::Project (to ~1e-3 px; float arithmetic). The distortion
// formulas are templates shared with camera.cpp, so both paths use one model.
#pragma once

#include <cmath>
#include <limits>

#include "core/camera.hpp"

namespace scenecal {

namespace camera_detail {

// OpenCV radial-tangential distortion (cv::projectPoints) of the normalised
// point (x, y); k = {k1, k2, p1, p2, k3}.
template <typename T>
inline void DistortRadTan(const T* k, T x, T y, T* x_distorted, T* y_distorted) {
  const T r2 = x * x + y * y;
  const T radial = T(1) + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
  const T xy2 = T(2) * x * y;
  *x_distorted = x * radial + k[2] * xy2 + k[3] * (r2 + T(2) * x * x);
  *y_distorted = y * radial + k[2] * (r2 + T(2) * y * y) + k[3] * xy2;
}

// OpenCV fisheye (cv::fisheye::projectPoints) model: factor that maps the
// normalised point (x, y) with r = |(x, y)| to the distorted one,
// theta_d / r with theta = atan(r) and theta_d = theta (1 + k1 t^2 + k2 t^4 +
// k3 t^6 + k4 t^8). OpenCV uses 1 when r <= 1e-8; so do we.
template <typename T>
inline T EquidistantScale(const T* k, T r, T theta) {
  if (r <= T(1e-8)) return T(1);
  const T t2 = theta * theta;
  const T theta_d = theta * (T(1) + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
  return theta_d / r;
}

}  // namespace camera_detail

// Flat float copy of a CameraModel plus the validity bounds Project applies.
struct ProjectionParams {
  float fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  // radtan: k1 k2 p1 p2 k3 (k3 = 0 when absent); equidistant: k1..k4, 0;
  // pinhole: zeros.
  float k[5] = {0, 0, 0, 0, 0};
  CameraModelKind kind = CameraModelKind::kPinhole;
  int width = 0, height = 0;  // pixels
  // Accepted pixel range, [u_min, u_max) x [v_min, v_max): the image
  // [-0.5, width - 0.5) x [-0.5, height - 0.5) shrunk by the margin.
  float u_min = 0, u_max = 0, v_min = 0, v_max = 0;
  float min_depth = 1e-6f;  // metres; points with z <= min_depth are rejected
  // Fold-back guard (CameraModel::MonotonicDistortionLimitSquared): radtan
  // rejects normalised r^2 >= limit, equidistant rejects theta^2 >= limit.
  float monotonic_limit_squared = std::numeric_limits<float>::infinity();
};

ProjectionParams MakeProjectionParams(const CameraModel& camera, double margin_px = 0.0,
                                      double min_depth = 1e-6);

// Projects a camera-frame point (metres) to the pixel (*u, *v) with the same
// rules as CameraModel::Project; *u, *v are written when the point is in front.
inline bool ProjectFast(const ProjectionParams& params, float x, float y, float z, float* u, float* v) {
  if (!(z > params.min_depth)) return false;
  const float inverse_z = 1.0f / z;
  float xn = x * inverse_z;
  float yn = y * inverse_z;
  bool in_model_range = true;
  switch (params.kind) {
    case CameraModelKind::kPinhole:
      break;
    case CameraModelKind::kRadTan: {
      const float r2 = xn * xn + yn * yn;
      in_model_range = r2 < params.monotonic_limit_squared;
      camera_detail::DistortRadTan(params.k, xn, yn, &xn, &yn);
      break;
    }
    case CameraModelKind::kEquidistant: {
      const float r = std::sqrt(xn * xn + yn * yn);
      const float theta = std::atan(r);
      in_model_range = theta * theta < params.monotonic_limit_squared;
      const float scale = camera_detail::EquidistantScale(params.k, r, theta);
      xn *= scale;
      yn *= scale;
      break;
    }
  }
  *u = params.fx * xn + params.cx;
  *v = params.fy * yn + params.cy;
  return in_model_range && *u >= params.u_min && *u < params.u_max && *v >= params.v_min &&
         *v < params.v_max;
}

}  // namespace scenecal
