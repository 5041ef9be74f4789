#include "core/swathe.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/hash.hpp"
#include "core/validation.hpp"

namespace scenecal {

bool SwatheOptions::IsValid(std::string* why) const {
  if (!(min_range_m >= 0.0) || !(max_range_m > min_range_m) || !std::isfinite(max_range_m))
    return Invalid(why, "ranges must satisfy 0 <= min_range_m < max_range_m (metres, finite)");
  if (!(min_depth_m > 0.0) || !std::isfinite(min_depth_m)) return Invalid(why, "min_depth_m must be > 0 (metres)");
  if (occlusion_cell_px < 0) return Invalid(why, "occlusion_cell_px must be 0 (automatic) or positive");
  if (!(occlusion_relative_margin >= 0.0) || !(occlusion_absolute_margin_m >= 0.0) ||
      !std::isfinite(occlusion_relative_margin) || !std::isfinite(occlusion_absolute_margin_m))
    return Invalid(why, "occlusion margins must be finite and >= 0");
  if (!(refresh_border_px >= 0.0) || !std::isfinite(refresh_border_px))
    return Invalid(why, "refresh_border_px must be >= 0 (pixels)");
  if (!(blur_px_per_point_stride >= 0.0) || !std::isfinite(blur_px_per_point_stride))
    return Invalid(why, "blur_px_per_point_stride must be >= 0 (pixels; 0 = every point)");
  return true;
}

SwatheImages SwatheImages::Prepare(const cv::Mat& intensity, const NormalisationOptions& normalisation) {
  SwatheImages images;
  const cv::Mat plain = NormaliseImage(intensity, normalisation.intensity, normalisation.lower_percentile,
                                       normalisation.upper_percentile);
  if (plain.empty()) return images;
  if (normalisation.intensity_highpass_width_fraction > 0.0) {
    // The sharp (final) stages score the texture; the blurred coarse stages
    // keep the whole image, whose large regions give the wide basin.
    images.plain = plain;
    images.sharp =
        NormaliseImage(HighPassImage(intensity, normalisation.intensity_highpass_width_fraction * intensity.cols),
                       normalisation.intensity, normalisation.lower_percentile, normalisation.upper_percentile);
  } else {
    images.sharp = plain;
  }
  return images;
}

SceneSwathe SceneSwathe::Build(const Scene& scene, const CameraInfo& camera, const cv::Mat& intensity,
                               const std::vector<const LidarScan*>& scans, const SwatheOptions& options,
                               const NormalisationOptions& normalisation) {
  return Build(scene, camera, SwatheImages::Prepare(intensity, normalisation), scans, options, normalisation);
}

SceneSwathe SceneSwathe::Build(const Scene& scene, const CameraInfo& camera, const SwatheImages& images,
                               const std::vector<const LidarScan*>& scans, const SwatheOptions& options,
                               const NormalisationOptions& normalisation) {
  SceneSwathe swathe;
  swathe.camera_ = scene.camera;
  swathe.lidar_ = scene.lidar;
  swathe.image_t_us_ = scene.image_t_us;
  swathe.scan_begin_.push_back(0);
  if (scans.size() != scene.scans.size() || images.sharp.empty() || images.sharp.cols != camera.model.width ||
      images.sharp.rows != camera.model.height) {
    return swathe;
  }
  swathe.image_sharp_ = images.sharp;
  swathe.image_plain_ = images.plain;
  swathe.blur_cache_ = images.blur ? images.blur : std::make_shared<SwatheBlurCache>();
  swathe.image_ = swathe.image_sharp_;
  double min_value = 0.0, max_value = 0.0;
  cv::minMaxLoc(swathe.image_, &min_value, &max_value);
  swathe.image_constant_ = !(max_value - min_value > 1e-6);
  // Half a pixel of margin: bilinear sampling needs the right and lower neighbours.
  swathe.projection_ = MakeProjectionParams(camera.model, 0.5, options.min_depth_m);

  swathe.T_base_camera_ = camera.T_base_camera;
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
    swathe.scan_t_us_.push_back(scene.scans[s].t_us);
    swathe.T_basek_basej_.push_back(scene.scans[s].T_basek_basej);
  }
  swathe.ComposeScanPoses(swathe.T_basek_basej_);
  swathe.reflectance01_ = ValueNormaliser::FitAndApply(reflectance, normalisation.reflectance,
                                                       normalisation.lower_percentile, normalisation.upper_percentile);
  // Judged after the mapping: e.g. `none` on reflectances beyond 1 clamps them all to 1.
  const auto [min_it, max_it] = std::minmax_element(swathe.reflectance01_.begin(), swathe.reflectance01_.end());
  swathe.reflectance_constant_ = swathe.reflectance01_.empty() || !(*max_it - *min_it > 1e-6f);
  swathe.visible_.assign(swathe.x_.size(), 1);
  // Blurring keeps the image within these bounds (a convex combination of its values).
  using swathe_detail::AllBounded;
  swathe.values_bounded_ = swathe.image_.type() == CV_32FC1 && AllBounded(swathe.reflectance01_);
  for (const cv::Mat* image : {&swathe.image_sharp_, &swathe.image_plain_}) {
    for (int v = 0; v < image->rows && swathe.values_bounded_; ++v) {
      swathe.values_bounded_ = AllBounded({image->ptr<float>(v), static_cast<std::size_t>(image->cols)});
    }
  }
  return swathe;
}

int PointStrideForBlur(double sigma_px, double blur_px_per_point_stride) {
  if (!(blur_px_per_point_stride > 0.0) || !(sigma_px > 0.0)) return 1;
  return std::clamp(static_cast<int>(sigma_px / blur_px_per_point_stride), 1, 64);
}

void SceneSwathe::ApplyPointStride() {
  if (point_stride_ <= 1) {
    unstrided_visible_.clear();
    return;
  }
  unstrided_visible_ = visible_;
  const auto stride = static_cast<std::size_t>(point_stride_);
  for (std::size_t i = 0; i < visible_.size(); ++i) {
    if (i % stride != 0) visible_[i] = 0;
  }
}

void SceneSwathe::SetImageBlur(double sigma_px, int point_stride) {
  point_stride = std::max(1, point_stride);
  if (point_stride != point_stride_) {
    if (!unstrided_visible_.empty()) visible_ = unstrided_visible_;
    point_stride_ = point_stride;
    ApplyPointStride();
  }
  if (image_sharp_.empty()) return;
  const double sigma = sigma_px > 0.0 ? sigma_px : 0.0;
  // The alternating scheme sets the blur of every alternation, mostly the one
  // already there: blurring again would give the same image (~6 % of a run).
  if (sigma == blur_sigma_px_) return;
  blur_sigma_px_ = sigma;
  if (sigma == 0.0) {
    image_ = image_sharp_;
    return;
  }
  // The frame's other swathes (range bands, other lidars' pairs) blur the same
  // image by the same sigma: one copy, made once, shared read-only.
  const std::lock_guard<std::mutex> lock(blur_cache_->mutex);
  if (blur_cache_->blurred.empty() || blur_cache_->sigma_px != sigma) {
    const cv::Mat& whole = image_plain_.empty() ? image_sharp_ : image_plain_;
    blur_cache_->blurred = GaussianBlurAnyWidth(whole, sigma);
    blur_cache_->sigma_px = sigma;
  }
  image_ = blur_cache_->blurred;
}

void SceneSwathe::ComposeScanPoses(const std::vector<Eigen::Isometry3d>& T_basek_basej) {
  const Eigen::Isometry3d T_camera_base = T_base_camera_.inverse();
  T_camerak_cameraj_.clear();
  for (const Eigen::Isometry3d& T : T_basek_basej) T_camerak_cameraj_.push_back(T_camera_base * T * T_base_camera_);
}

std::size_t SceneSwathe::ThinByImageDensity(const CameraModel& model, const Eigen::Isometry3d& T_camera_lidar,
                                            int cell_px, int max_points_per_cell, double margin_px) {
  if (cell_px <= 0 || max_points_per_cell <= 0 || image_.empty() || model.width != image_.cols ||
      model.height != image_.rows) {
    return PointCount();
  }
  const double margin = std::max(0.0, margin_px);
  const int cells_u = static_cast<int>(std::ceil((model.width + 2.0 * margin) / cell_px));
  const int cells_v = static_cast<int>(std::ceil((model.height + 2.0 * margin) / cell_px));
  constexpr std::uint32_t kOutside = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> cell_of_point(PointCount(), kOutside);
  std::vector<std::uint32_t> points_in_cell(static_cast<std::size_t>(cells_u) * static_cast<std::size_t>(cells_v), 0);
  for (std::size_t scan = 0; scan < ScanCount(); ++scan) {
    const Eigen::Isometry3d T_camerak_lidar = T_camerak_cameraj_[scan] * T_camera_lidar;
    for (std::size_t i = scan_begin_[scan]; i < scan_begin_[scan + 1]; ++i) {
      Eigen::Vector2d pixel;
      if (!model.Project(T_camerak_lidar * Eigen::Vector3d(x_[i], y_[i], z_[i]), &pixel, -margin,
                         static_cast<double>(projection_.min_depth))) {
        continue;
      }
      const int cu = std::clamp(static_cast<int>((pixel.x() + 0.5 + margin) / cell_px), 0, cells_u - 1);
      const int cv = std::clamp(static_cast<int>((pixel.y() + 0.5 + margin) / cell_px), 0, cells_v - 1);
      cell_of_point[i] = static_cast<std::uint32_t>(cv * cells_u + cu);
      ++points_in_cell[cell_of_point[i]];
    }
  }
  std::size_t kept = 0;
  std::vector<std::size_t> scan_begin{0};
  const auto seed = Mix64(static_cast<std::uint64_t>(image_t_us_));
  for (std::size_t scan = 0; scan < ScanCount(); ++scan) {
    for (std::size_t i = scan_begin_[scan]; i < scan_begin_[scan + 1]; ++i) {
      if (cell_of_point[i] == kOutside) continue;
      const std::uint32_t crowd = points_in_cell[cell_of_point[i]];
      // Keep with probability max / crowd: compare 32 uniform bits with the threshold.
      const bool keep = crowd <= static_cast<std::uint32_t>(max_points_per_cell) ||
                        (Mix64(seed ^ i) >> 32) * static_cast<double>(crowd) <
                            static_cast<double>(max_points_per_cell) * 4294967296.0;
      if (!keep) continue;
      x_[kept] = x_[i];
      y_[kept] = y_[i];
      z_[kept] = z_[i];
      reflectance01_[kept] = reflectance01_[i];
      visible_[kept] = visible_[i];
      ++kept;
    }
    scan_begin.push_back(kept);
  }
  for (auto* values : {&x_, &y_, &z_, &reflectance01_}) {
    values->resize(kept);
    values->shrink_to_fit();
  }
  visible_.resize(kept);
  visible_.shrink_to_fit();
  scan_begin_ = std::move(scan_begin);
  return kept;
}

std::size_t SceneSwathe::VisibleCount() const {
  return static_cast<std::size_t>(std::count(visible_.begin(), visible_.end(), std::uint8_t{1}));
}

std::size_t SceneSwathe::CountProjected(const Eigen::Isometry3d& T_camera_lidar) const {
  // Before a coarse stage's stride: which scenes have enough points does not change with the stage.
  const std::vector<std::uint8_t>& mask = unstrided_visible_.empty() ? visible_ : unstrided_visible_;
  std::size_t count = 0;
  ForEachProjectedBlock(T_camera_lidar, false,
                        [&](std::size_t begin, int n, const float*, const float*, const float*,
                            const std::int32_t* accepted) {
                          for (int k = 0; k < n; ++k) count += (accepted[k] != 0 && mask[begin + k] != 0) ? 1 : 0;
                        });
  return count;
}

std::vector<std::size_t> SceneSwathe::CountProjectedPerScan(const Eigen::Isometry3d& T_camera_lidar) const {
  std::vector<std::size_t> counts(ScanCount(), 0);
  ForEachProjected(T_camera_lidar, false, [&](std::size_t i, float, float, float, float) {
    // scan_begin_ is ascending: the scan of point i is the last one starting at or before i.
    const auto scan = std::upper_bound(scan_begin_.begin(), scan_begin_.end(), i) - scan_begin_.begin() - 1;
    ++counts[static_cast<std::size_t>(scan)];
  });
  return counts;
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
  const std::size_t projected = RefreshVisibilityMask(T_camera_lidar, options);
  ApplyPointStride();
  return projected;
}

std::size_t SceneSwathe::RefreshVisibilityMask(const Eigen::Isometry3d& T_camera_lidar, const SwatheOptions& options) {
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
  const auto border = static_cast<float>(options.refresh_border_px);
  if (!options.occlusion && border <= 0.0f) return projected;
  const auto relative = static_cast<float>(1.0 + options.occlusion_relative_margin);
  const auto absolute = static_cast<float>(options.occlusion_absolute_margin_m);
  const float u_last = static_cast<float>(image_.cols - 1) - border;
  const float v_last = static_cast<float>(image_.rows - 1) - border;
  // With a border, points that do not project now (outside, behind) stay out too: a fixed set.
  if (border > 0.0f) std::fill(visible_.begin(), visible_.end(), std::uint8_t{0});
  ForEachProjected(T_camera_lidar, false, [&](std::size_t i, float, float u, float v, float depth) {
    const bool occluded = options.occlusion && depth > nearest[cell_of(u, v)] * relative + absolute;
    const bool near_border = u < border || v < border || u > u_last || v > v_last;
    visible_[i] = (occluded || near_border) ? 0 : 1;
  });
  return projected;
}

Matrix6d SceneSwathe::AlignmentInformation(const Eigen::Isometry3d& T_camera_lidar, double* gradient_weight) const {
  Matrix6d information = Matrix6d::Zero();
  double weight = 0.0;
  if (gradient_weight != nullptr) *gradient_weight = 0.0;
  if (image_.empty() || T_camerak_cameraj_.empty()) return information;
  const Eigen::Matrix3d R_camera_lidar = T_camera_lidar.linear();
  // Central differences one pixel either side need the bilinear footprint inside the image.
  const float u_low = 1.0f, v_low = 1.0f;
  const float u_high = static_cast<float>(image_.cols) - 2.0f, v_high = static_cast<float>(image_.rows) - 2.0f;
  const double fx = projection_.fx, fy = projection_.fy;
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Isometry3d T_camerak_lidar = T_camerak_cameraj_[scan] * T_camera_lidar;
    const Eigen::Matrix3d R_camerak_cameraj = T_camerak_cameraj_[scan].linear();
    const std::size_t begin = scan_begin_[scan], end = scan_begin_[scan + 1];
    for (std::size_t i = begin; i < end; ++i) {
      if (!visible_[i]) continue;
      double contrast = 0.0;  // reflectance steps to the neighbours along the scan
      if (i > begin) contrast += std::abs(reflectance01_[i] - reflectance01_[i - 1]);
      if (i + 1 < end) contrast += std::abs(reflectance01_[i + 1] - reflectance01_[i]);
      if (!(contrast > 0.0)) continue;
      const Eigen::Vector3d p_lidar(x_[i], y_[i], z_[i]);
      const Eigen::Vector3d c = T_camerak_lidar * p_lidar;
      float u = 0.0f, v = 0.0f;
      if (!ProjectFast(projection_, static_cast<float>(c.x()), static_cast<float>(c.y()),
                       static_cast<float>(c.z()), &u, &v))
        continue;
      if (!(u >= u_low && u < u_high && v >= v_low && v < v_high)) continue;
      const double di_du = 0.5 * (Sample(u + 1.0f, v) - Sample(u - 1.0f, v));
      const double di_dv = 0.5 * (Sample(u, v + 1.0f) - Sample(u, v - 1.0f));
      const double inverse_z = 1.0 / c.z();
      // [dI/du dI/dv] * d(u, v)/dc for the pinhole projection.
      const Eigen::RowVector3d di_dc(di_du * fx * inverse_z, di_dv * fy * inverse_z,
                                     -(di_du * fx * c.x() + di_dv * fy * c.y()) * inverse_z * inverse_z);
      const Eigen::RowVector3d di_drho = di_dc * R_camerak_cameraj;
      // dc/dphi = -R_camerak_cameraj [R_camera_lidar p]x, so di/dphi = (R_camera_lidar p) x (di/drho)^T.
      const Eigen::Vector3d di_dphi = (R_camera_lidar * p_lidar).cross(di_drho.transpose());
      Vector6d j;
      j << di_drho.transpose(), di_dphi;
      information.noalias() += (contrast * j) * j.transpose();  // fixed-size outer product: vectorised
      weight += contrast * (di_du * di_du + di_dv * di_dv);
    }
  }
  if (gradient_weight != nullptr) *gradient_weight = weight;
  return information;
}

}  // namespace scenecal
