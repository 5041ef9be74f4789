// A scene prepared for cost evaluation: the swathe of lidar points of one
// scene (core/scenes.hpp) and the image of its camera frame.
//
// Everything that does not depend on the extrinsic is done once here: each
// scan's relative pose is precomposed with the known camera transform,
//   T_camerak_cameraj = T_camera_base * T_basek_basej * T_base_camera,
// points are stored float32 structure-of-arrays in the lidar frame, their
// reflectance is normalised to [0, 1] (fitted on the scene's swathe), and the
// image is normalised once. An evaluation with a candidate T_camera_lidar only
// composes M_j = T_camerak_cameraj * T_camera_lidar per scan (float 3x4) and
// maps each point p_camera = M_j * p_lidar.
//
// Occlusion: a per-point visibility mask computed by RefreshVisibility at a
// given estimate with a coarse z-buffer (a point farther than the nearest
// point of its cell by a relative and an absolute margin is hidden). It is
// refreshed between optimiser runs, never inside one, so the cost does not jump.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera_kernel.hpp"
#include "core/normalisation.hpp"
#include "core/rig.hpp"
#include "core/scenes.hpp"

namespace scenecal {

struct SwatheOptions {
  double min_range_m = 1.0;    // lidar points nearer than this (lidar frame) are dropped (vehicle body, noise)
  double max_range_m = 100.0;  // and farther than this
  double min_depth_m = 0.2;    // camera-frame depth below which a point does not project
  // Z-buffer occlusion test. Cell size in pixels; 0 = automatic (image width / 80, at least 4).
  bool occlusion = true;
  int occlusion_cell_px = 0;
  double occlusion_relative_margin = 0.2;  // hidden if depth > nearest * (1 + relative) + absolute
  double occlusion_absolute_margin_m = 0.3;

  bool IsValid(std::string* why = nullptr) const;
};

class SceneSwathe {
 public:
  SceneSwathe() = default;

  // Builds the swathe of `scene` seen by `camera`: scans[i] is the scan at
  // scene.scans[i].t_us (same order and size). `intensity` is the frame's
  // GreyImage intensity (CV_32FC1 in [0, 1]); it is normalised here with
  // normalisation.intensity and reflectances with normalisation.reflectance.
  // A size mismatch leaves an empty swathe (PointCount() == 0).
  static SceneSwathe Build(const Scene& scene, const CameraInfo& camera, const cv::Mat& intensity,
                           const std::vector<const LidarScan*>& scans, const SwatheOptions& options,
                           const NormalisationOptions& normalisation);

  const std::string& Camera() const { return camera_; }
  const std::string& Lidar() const { return lidar_; }
  TimeUs ImageTime() const { return image_t_us_; }
  std::size_t PointCount() const { return x_.size(); }
  std::size_t ScanCount() const { return T_camerak_cameraj_.size(); }
  std::size_t VisibleCount() const;
  // True when the normalised image or normalised reflectances are constant (no information).
  bool ImageIsConstant() const { return image_constant_; }
  bool ReflectanceIsConstant() const { return reflectance_constant_; }

  // Calls visit(point_index, reflectance01, u, v, depth_m) for every point
  // (visible only, when visible_only) that projects into the image under
  // T_camera_lidar. u, v are pixels with room for bilinear sampling.
  template <typename Visitor>
  void ForEachProjected(const Eigen::Isometry3d& T_camera_lidar, bool visible_only, Visitor&& visit) const;

  // Bilinear intensity (normalised, [0, 1]) at pixel (u, v) inside the image.
  float Sample(float u, float v) const {
    const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
    const float fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
    const float* row0 = image_.ptr<float>(v0) + u0;
    const float* row1 = image_.ptr<float>(v0 + 1) + u0;
    return (1.0f - fv) * ((1.0f - fu) * row0[0] + fu * row0[1]) + fv * ((1.0f - fu) * row1[0] + fu * row1[1]);
  }

  // Recomputes the visibility mask with the z-buffer at T_camera_lidar; points
  // that do not project at this estimate stay visible. Returns the number of
  // points that project (before hiding).
  std::size_t RefreshVisibility(const Eigen::Isometry3d& T_camera_lidar, const SwatheOptions& options);

  // Number of points that project (visible ones only) under T_camera_lidar.
  std::size_t CountProjected(const Eigen::Isometry3d& T_camera_lidar) const;
  // Sum of the lidar-frame coordinates (metres) of those points; *count gets their number.
  Eigen::Vector3d SumProjectedLidarPoints(const Eigen::Isometry3d& T_camera_lidar, std::size_t* count) const;

  // Gaussian blur of the working image (pixels, 1-sigma); 0 restores the sharp
  // image. For coarse-to-fine smoothing between optimiser runs, never inside one.
  void SetImageBlur(double sigma_px);

  const cv::Mat& Image() const { return image_; }

 private:
  std::string camera_, lidar_;
  TimeUs image_t_us_ = 0;
  ProjectionParams projection_;
  cv::Mat image_;        // CV_32FC1, normalised; the working image (possibly blurred)
  cv::Mat image_sharp_;  // CV_32FC1, normalised, never blurred
  bool image_constant_ = false;
  bool reflectance_constant_ = false;
  // Points in the lidar frame (metres) and normalised reflectance, SoA.
  std::vector<float> x_, y_, z_, reflectance01_;
  std::vector<std::uint8_t> visible_;
  std::vector<std::size_t> scan_begin_;  // points of scan i: [scan_begin_[i], scan_begin_[i + 1])
  std::vector<Eigen::Isometry3d> T_camerak_cameraj_;
};

template <typename Visitor>
void SceneSwathe::ForEachProjected(const Eigen::Isometry3d& T_camera_lidar, bool visible_only,
                                   Visitor&& visit) const {
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Matrix<float, 3, 4> m =
        (T_camerak_cameraj_[scan] * T_camera_lidar).matrix().topRows<3>().cast<float>();
    const std::size_t end = scan_begin_[scan + 1];
    for (std::size_t i = scan_begin_[scan]; i < end; ++i) {
      if (visible_only && !visible_[i]) continue;
      const float px = m(0, 0) * x_[i] + m(0, 1) * y_[i] + m(0, 2) * z_[i] + m(0, 3);
      const float py = m(1, 0) * x_[i] + m(1, 1) * y_[i] + m(1, 2) * z_[i] + m(1, 3);
      const float pz = m(2, 0) * x_[i] + m(2, 1) * y_[i] + m(2, 2) * z_[i] + m(2, 3);
      float u, v;
      if (!ProjectFast(projection_, px, py, pz, &u, &v)) continue;
      visit(i, reflectance01_[i], u, v, pz);
    }
  }
}

}  // namespace scenecal
