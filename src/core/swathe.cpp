#include "core/swathe.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace scenecal {

bool SwatheOptions::IsValid(std::string* why) const {
  const auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!(min_range_m >= 0.0) || !(max_range_m > min_range_m) || !std::isfinite(max_range_m))
    return fail("ranges must satisfy 0 <= min_range_m < max_range_m (metres, finite)");
  if (!(min_depth_m > 0.0) || !std::isfinite(min_depth_m)) return fail("min_depth_m must be > 0 (metres)");
  if (occlusion_cell_px < 0) return fail("occlusion_cell_px must be 0 (automatic) or positive");
  if (!(occlusion_relative_margin >= 0.0) || !(occlusion_absolute_margin_m >= 0.0))
    return fail("occlusion margins must be >= 0");
  return true;
}

SceneSwathe SceneSwathe::Build(const Scene& scene, const CameraInfo& camera, const cv::Mat& intensity,
                               const std::vector<const LidarScan*>& scans, const SwatheOptions& options,
                               const NormalisationOptions& normalisation) {
  SceneSwathe swathe;
  swathe.camera_ = scene.camera;
  swathe.lidar_ = scene.lidar;
  swathe.image_t_us_ = scene.image_t_us;
  swathe.scan_begin_.push_back(0);
  if (scans.size() != scene.scans.size() || intensity.empty() || intensity.cols != camera.model.width ||
      intensity.rows != camera.model.height) {
    return swathe;
  }
  swathe.image_ = NormaliseImage(intensity, normalisation.intensity, normalisation.lower_percentile,
                                 normalisation.upper_percentile);
  if (swathe.image_.empty()) return swathe;
  swathe.image_sharp_ = swathe.image_;
  double min_value = 0.0, max_value = 0.0;
  cv::minMaxLoc(swathe.image_, &min_value, &max_value);
  swathe.image_constant_ = !(max_value - min_value > 1e-6);
  // Half a pixel of margin: bilinear sampling needs the right and lower neighbours.
  swathe.projection_ = MakeProjectionParams(camera.model, 0.5, options.min_depth_m);

  const Eigen::Isometry3d T_camera_base = camera.T_base_camera.inverse();
  std::vector<float> reflectance;
  const double min_range2 = options.min_range_m * options.min_range_m;
  const double max_range2 = options.max_range_m * options.max_range_m;
  for (std::size_t s = 0; s < scans.size(); ++s) {
    if (scans[s] == nullptr) continue;
    for (const LidarPoint& p : scans[s]->points) {
      const double range2 = static_cast<double>(p.x) * p.x + static_cast<double>(p.y) * p.y +
                            static_cast<double>(p.z) * p.z;
      if (range2 < min_range2 || range2 > max_range2 || !std::isfinite(p.reflectance)) continue;
      swathe.x_.push_back(p.x);
      swathe.y_.push_back(p.y);
      swathe.z_.push_back(p.z);
      reflectance.push_back(p.reflectance);
    }
    swathe.scan_begin_.push_back(swathe.x_.size());
    swathe.T_camerak_cameraj_.push_back(T_camera_base * scene.scans[s].T_basek_basej * camera.T_base_camera);
  }
  const ValueNormaliser normaliser =
      ValueNormaliser::Fit(reflectance, normalisation.reflectance, normalisation.lower_percentile,
                           normalisation.upper_percentile);
  swathe.reflectance01_.resize(reflectance.size());
  normaliser.Apply(reflectance, swathe.reflectance01_);
  // Judged after the mapping: e.g. `none` on reflectances beyond 1 clamps them all to 1.
  const auto [min_it, max_it] = std::minmax_element(swathe.reflectance01_.begin(), swathe.reflectance01_.end());
  swathe.reflectance_constant_ = swathe.reflectance01_.empty() || !(*max_it - *min_it > 1e-6f);
  swathe.visible_.assign(swathe.x_.size(), 1);
  return swathe;
}

void SceneSwathe::SetImageBlur(double sigma_px) {
  if (image_sharp_.empty()) return;
  if (!(sigma_px > 0.0)) {
    image_ = image_sharp_;
    return;
  }
  cv::Mat blurred;
  cv::GaussianBlur(image_sharp_, blurred, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REFLECT);
  image_ = blurred;
}

std::size_t SceneSwathe::VisibleCount() const {
  return static_cast<std::size_t>(std::count(visible_.begin(), visible_.end(), std::uint8_t{1}));
}

std::size_t SceneSwathe::CountProjected(const Eigen::Isometry3d& T_camera_lidar) const {
  std::size_t count = 0;
  ForEachProjected(T_camera_lidar, true, [&](std::size_t, float, float, float, float) { ++count; });
  return count;
}

Eigen::Vector3d SceneSwathe::SumProjectedLidarPoints(const Eigen::Isometry3d& T_camera_lidar,
                                                     std::size_t* count) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  ForEachProjected(T_camera_lidar, true, [&](std::size_t i, float, float, float, float) {
    sum += Eigen::Vector3d(x_[i], y_[i], z_[i]);
    ++n;
  });
  if (count != nullptr) *count = n;
  return sum;
}

std::size_t SceneSwathe::RefreshVisibility(const Eigen::Isometry3d& T_camera_lidar, const SwatheOptions& options) {
  std::fill(visible_.begin(), visible_.end(), std::uint8_t{1});
  if (image_.empty()) return 0;
  const int cell = options.occlusion_cell_px > 0 ? options.occlusion_cell_px : std::max(4, image_.cols / 80);
  const int cells_u = (image_.cols + cell - 1) / cell;
  const int cells_v = (image_.rows + cell - 1) / cell;
  std::vector<float> nearest(static_cast<std::size_t>(cells_u) * static_cast<std::size_t>(cells_v),
                             std::numeric_limits<float>::infinity());
  const auto cell_of = [&](float u, float v) {
    return static_cast<std::size_t>(static_cast<int>(v) / cell) * static_cast<std::size_t>(cells_u) +
           static_cast<std::size_t>(static_cast<int>(u) / cell);
  };
  std::size_t projected = 0;
  ForEachProjected(T_camera_lidar, false, [&](std::size_t, float, float u, float v, float depth) {
    float& n = nearest[cell_of(u, v)];
    n = std::min(n, depth);
    ++projected;
  });
  if (!options.occlusion) return projected;
  const auto relative = static_cast<float>(1.0 + options.occlusion_relative_margin);
  const auto absolute = static_cast<float>(options.occlusion_absolute_margin_m);
  ForEachProjected(T_camera_lidar, false, [&](std::size_t i, float, float u, float v, float depth) {
    if (depth > nearest[cell_of(u, v)] * relative + absolute) visible_[i] = 0;
  });
  return projected;
}

}  // namespace scenecal
