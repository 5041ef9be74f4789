// Camera models: pinhole, radial-tangential (OpenCV's k1 k2 p1 p2 [k3]) and
// equidistant fisheye (OpenCV's fisheye k1..k4). Frame: x right, y down,
// z forward (optical axis). Pixel coordinates: (0, 0) is the centre of the
// top-left pixel, as in OpenCV.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/enum_names.hpp"

namespace scenecal {

enum class CameraModelKind { kPinhole, kRadTan, kEquidistant };
inline constexpr auto kCameraModelKindNames = MakeEnumNames<CameraModelKind>(
    {{CameraModelKind::kPinhole, "pinhole"}, {CameraModelKind::kRadTan, "radtan"},
     {CameraModelKind::kEquidistant, "equidistant"}});

// "pinhole" | "radtan" | "equidistant"; returns false for anything else.
bool ParseCameraModelKind(const std::string& name, CameraModelKind* kind);
const char* CameraModelKindName(CameraModelKind kind);

struct CameraModel {
  int width = 0;   // pixels
  int height = 0;  // pixels
  CameraModelKind kind = CameraModelKind::kPinhole;
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  // radtan: k1 k2 p1 p2 [k3]; equidistant: k1 k2 k3 k4; pinhole: empty.
  std::vector<double> distortion;

  // Checks sizes, finite positive focal lengths and the distortion length
  // expected by the model; on failure says why in *why (if given).
  bool IsValid(std::string* why = nullptr) const;

  // Projects a point given in the camera frame (metres). Returns false when the
  // point is not in front of the camera (z <= min_depth) or when the pixel
  // falls outside the image shrunk by margin_px on every side; *pixel is still
  // written when the point is in front, so callers can inspect it.
  // Accepted pixels: u in [-0.5 + margin, width - 0.5 - margin), v likewise
  // with height, i.e. pixels whose rounded index floor(u + 0.5) lies in the
  // image (pixel squares, not only centres). Also false beyond the range where
  // the distortion is monotonic (MonotonicDistortionLimitSquared), where the
  // polynomial folds far off-axis points back into the image.
  bool Project(const Eigen::Vector3d& p_camera, Eigen::Vector2d* pixel, double margin_px = 0.0,
               double min_depth = 1e-6) const;

  // Distortion-free normalised coordinates (x/z, y/z) -> pixel, no checks.
  Eigen::Vector2d DistortAndScale(const Eigen::Vector2d& normalised) const;

  // Pixel -> ray direction in the camera frame with z = 1 (iterative inverse of
  // the distortion; exact for pinhole). Pixels beyond the distortion's
  // monotonic range (unreachable by Project) give the ray at that limit.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;

  // The distortion is monotonic in the radius (d r_distorted / d r > 0) for
  // s < this limit, where s is the normalised radius squared (x^2 + y^2)/z^2
  // for radtan and theta^2 (angle from the optical axis, rad^2) for
  // equidistant; at most (pi/2)^2 for equidistant, infinity for pinhole and
  // for radtan distortions that never fold.
  double MonotonicDistortionLimitSquared() const;
};

}  // namespace scenecal
