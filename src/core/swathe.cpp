#include "core/swathe.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <span>

#include <ceres/jet.h>
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

namespace swathe_detail {

// AVX2 without FMA: no contraction of a * b + c, so the same floats as the SSE2 clone.
__attribute__((target_clones("avx2", "default"))) void ProjectAnyBlock(
    const ProjectionParams& params, const Eigen::Matrix<float, 3, 4>& m, const float* __restrict x,
    const float* __restrict y, const float* __restrict z, const std::uint8_t* __restrict visible, int count,
    float* __restrict u_out, float* __restrict v_out, float* __restrict depth_out, std::int32_t* __restrict accepted) {
  switch (params.kind) {
    case CameraModelKind::kPinhole:
      ProjectBlock<CameraModelKind::kPinhole>(params, m, x, y, z, count, u_out, v_out, depth_out, accepted);
      for (int k = 0; k < count; ++k) accepted[k] &= static_cast<std::int32_t>(visible[k] != 0);
      break;
    case CameraModelKind::kRadTan:
      ProjectBlock<CameraModelKind::kRadTan>(params, m, x, y, z, count, u_out, v_out, depth_out, accepted);
      for (int k = 0; k < count; ++k) accepted[k] &= static_cast<std::int32_t>(visible[k] != 0);
      break;
    case CameraModelKind::kEquidistant:
      for (int k = 0; k < count; ++k) {
        const float px = m(0, 0) * x[k] + m(0, 1) * y[k] + m(0, 2) * z[k] + m(0, 3);
        const float py = m(1, 0) * x[k] + m(1, 1) * y[k] + m(1, 2) * z[k] + m(1, 3);
        depth_out[k] = m(2, 0) * x[k] + m(2, 1) * y[k] + m(2, 2) * z[k] + m(2, 3);
        accepted[k] = ProjectFast(params, px, py, depth_out[k], &u_out[k], &v_out[k]) && visible[k] != 0;
      }
      break;
  }
}

}  // namespace swathe_detail

namespace {

// HardBin (core/metric.hpp) for a finite v01 with |v01 * bins| < 2^31, with
// integer selects the vectoriser accepts (floating-point selects it refuses
// under -ftrapping-math): truncating the exact double product and clamping the
// integer to [0, bins - 1] gives HardBin's bin (its clamp of v01 to [0, 1]
// first maps v01 < 0 to bin 0 and v01 >= 1 to bins - 1, as this does).
inline std::int32_t HardBinOfBoundedValue(float v01, std::int32_t bins) {
  const auto bin = static_cast<std::int32_t>(static_cast<double>(v01) * static_cast<double>(bins));
  const std::int32_t low = bin > 0 ? bin : 0;
  return low < bins ? low : bins - 1;
}

// Values whose hard bins HardBinOfBoundedValue may compute (for any bin count up to kMaxBins).
constexpr float kBoundedValueLimit = 1e6f;

// True when every value is finite and within +-kBoundedValueLimit. (A loop
// the compiler vectorises: cv::checkRange took ~1 % of a calibration.)
bool AllBounded(std::span<const float> values) {
  int outside = 0;
  for (const float value : values) outside |= static_cast<int>(!(std::abs(value) < kBoundedValueLimit));  // NaN: outside
  return outside == 0;
}

}  // namespace

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
  // Blurring keeps the image within these bounds (a convex combination of its values).
  swathe.values_bounded_ = swathe.image_.type() == CV_32FC1 && AllBounded(swathe.reflectance01_);
  for (int v = 0; v < swathe.image_.rows && swathe.values_bounded_; ++v) {
    swathe.values_bounded_ = AllBounded({swathe.image_.ptr<float>(v), static_cast<std::size_t>(swathe.image_.cols)});
  }
  return swathe;
}

void SceneSwathe::SetImageBlur(double sigma_px) {
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
  cv::Mat blurred;
  cv::GaussianBlur(image_sharp_, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
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

namespace {

// The hard counts of one projected block of AddHardCounts (u, v, accepted from
// ProjectAnyBlock; x01 the block's reflectances). Compiled for AVX2 and for
// baseline x86-64, chosen at run time; no FMA, so both give the same bins.
__attribute__((target_clones("avx2", "default"))) std::size_t CountHardBlock(
    const float* __restrict image, std::int32_t stride, const float* __restrict u, const float* __restrict v,
    const std::int32_t* __restrict accepted, const float* __restrict x01, int count, std::int32_t reflectance_bins,
    std::int32_t intensity_bins, std::uint32_t* __restrict counts) {
  using swathe_detail::kBlock;
  using swathe_detail::kPrefetchDistance;
  alignas(64) std::int32_t offset[kBlock], bin[kBlock];
  alignas(64) float fraction_u[kBlock], fraction_v[kBlock];
  alignas(64) float top_left[kBlock], top_right[kBlock], bottom_left[kBlock], bottom_right[kBlock];
  // Integer pixel and fractions as BilinearSampler computes them (u, v >= 0 for
  // accepted points, so truncation is floor); rejected points get pixel (0, 0).
  std::int32_t accepted_count = 0;
  for (int k = 0; k < count; ++k) {
    // A bit mask, not a floating-point select (which would not vectorise).
    const std::uint32_t keep = 0u - static_cast<std::uint32_t>(accepted[k]);
    const float uk = std::bit_cast<float>(std::bit_cast<std::uint32_t>(u[k]) & keep);
    const float vk = std::bit_cast<float>(std::bit_cast<std::uint32_t>(v[k]) & keep);
    const auto u0 = static_cast<std::int32_t>(uk), v0 = static_cast<std::int32_t>(vk);
    fraction_u[k] = uk - static_cast<float>(u0);
    fraction_v[k] = vk - static_cast<float>(v0);
    offset[k] = v0 * stride + u0;
    accepted_count += accepted[k];
  }
  if (accepted_count == 0) return 0;
  // The only scalar part: four reads per point, scattered over the image. Every
  // point of the block is read (rejected ones at the cached pixel (0, 0)) and
  // counted with weight accepted[k] (0 or 1): no compaction, and no branch.
  // (Prefetching by rank among the accepted points instead measured no faster.)
  for (int k = 0; k < count; ++k) {
    if (k + kPrefetchDistance < count) {
      const float* ahead = image + offset[k + kPrefetchDistance];
      __builtin_prefetch(ahead);
      __builtin_prefetch(ahead + stride);
    }
    const float* row0 = image + offset[k];
    const float* row1 = row0 + stride;
    top_left[k] = row0[0];
    top_right[k] = row0[1];
    bottom_left[k] = row1[0];
    bottom_right[k] = row1[1];
  }
  // BilinearSampler's expression, term for term (bit-identical samples), then HardBin.
  for (int k = 0; k < count; ++k) {
    const float fu = fraction_u[k], fv = fraction_v[k];
    const float y01 = (1.0f - fv) * ((1.0f - fu) * top_left[k] + fu * top_right[k]) +
                      fv * ((1.0f - fu) * bottom_left[k] + fu * bottom_right[k]);
    bin[k] = HardBinOfBoundedValue(x01[k], reflectance_bins) * intensity_bins +
             HardBinOfBoundedValue(y01, intensity_bins);
  }
  for (int k = 0; k < count; ++k) counts[bin[k]] += static_cast<std::uint32_t>(accepted[k]);
  return static_cast<std::size_t>(accepted_count);
}

}  // namespace

std::size_t SceneSwathe::AddHardCounts(const Eigen::Isometry3d& T_camera_lidar, int reflectance_bins,
                                       int intensity_bins, std::uint32_t* counts) const {
  using namespace swathe_detail;
  if (image_.empty() || reflectance_bins < 1 || intensity_bins < 1) return 0;
  // Pixel offsets are int32 so that their loop vectorises, and the bins need
  // bounded values: otherwise (huge images, non-finite values) the generic path.
  // (The fast path reads pixel (0, 0) and its neighbours for rejected points: 2 x 2 pixels at least.)
  if (!values_bounded_ || image_.rows < 2 || image_.cols < 2 || reflectance_bins > HistogramOptions::kMaxBins ||
      intensity_bins > HistogramOptions::kMaxBins ||
      image_.total() + image_.step1() >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    const BilinearSampler sample = Sampler();
    std::size_t samples = 0;
    ForEachProjected(T_camera_lidar, true, [&](std::size_t, float x01, float u, float v, float) {
      ++counts[HardBin(x01, reflectance_bins) * intensity_bins + HardBin(sample(u, v), intensity_bins)];
      ++samples;
    });
    return samples;
  }
  const float* const image = image_.ptr<float>();
  const auto stride = static_cast<std::int32_t>(image_.step1());
  alignas(64) float u[kBlock], v[kBlock], depth[kBlock];
  alignas(64) std::int32_t accepted[kBlock];
  std::size_t samples = 0;
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Matrix<float, 3, 4> m =
        (T_camerak_cameraj_[scan] * T_camera_lidar).matrix().topRows<3>().cast<float>();
    const std::size_t end = scan_begin_[scan + 1];
    for (std::size_t begin = scan_begin_[scan]; begin < end; begin += kBlock) {
      const int count = static_cast<int>(std::min<std::size_t>(kBlock, end - begin));
      ProjectAnyBlock(projection_, m, x_.data() + begin, y_.data() + begin, z_.data() + begin,
                      visible_.data() + begin, count, u, v, depth, accepted);
      samples += CountHardBlock(image, stride, u, v, accepted, reflectance01_.data() + begin, count,
                                reflectance_bins, intensity_bins, counts);
    }
  }
  return samples;
}

namespace {

// d(u, v) / d(p_camera) of the camera model at the camera-frame point p
// (metres; in front). Distortion is differentiated with Jets through the same
// templates as ProjectFast / CameraModel::Project.
Eigen::Matrix<double, 2, 3> ProjectionJacobian(const ProjectionParams& params, const Eigen::Vector3d& p) {
  using Jet = ceres::Jet<double, 2>;
  const double inverse_z = 1.0 / p.z();
  const Jet xn(p.x() * inverse_z, 0), yn(p.y() * inverse_z, 1);
  Jet xd = xn, yd = yn;
  switch (params.kind) {
    case CameraModelKind::kPinhole:
      break;
    case CameraModelKind::kRadTan: {
      const Jet k[5] = {Jet(params.k[0]), Jet(params.k[1]), Jet(params.k[2]), Jet(params.k[3]), Jet(params.k[4])};
      camera_detail::DistortRadTan(k, xn, yn, &xd, &yd);
      break;
    }
    case CameraModelKind::kEquidistant: {
      const Jet k[4] = {Jet(params.k[0]), Jet(params.k[1]), Jet(params.k[2]), Jet(params.k[3])};
      // Away from the axis (r > 1e-8, where the model is smooth); on it the scale is 1.
      const Jet r = ceres::sqrt(xn * xn + yn * yn + Jet(1e-300));
      const Jet scale = camera_detail::EquidistantScale(k, r, ceres::atan(r));
      xd = xn * scale;
      yd = yn * scale;
      break;
    }
  }
  Eigen::Matrix2d d_distorted_d_normalised;
  d_distorted_d_normalised << xd.v[0], xd.v[1], yd.v[0], yd.v[1];
  Eigen::Matrix<double, 2, 3> d_normalised_d_p;
  d_normalised_d_p << inverse_z, 0.0, -p.x() * inverse_z * inverse_z, 0.0, inverse_z, -p.y() * inverse_z * inverse_z;
  const Eigen::Matrix2d focal = Eigen::Vector2d(params.fx, params.fy).asDiagonal();
  return focal * d_distorted_d_normalised * d_normalised_d_p;
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

}  // namespace

Vector6d SceneSwathe::SampleGradientSum(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                                        const Eigen::Vector3d& pivot_source, const CostGradient& dcost) const {
  Vector6d sum = Vector6d::Zero();
  if (image_.empty()) return sum;
  const Eigen::Vector3d pivot_camera = T_camera_lidar * pivot_source;
  std::size_t scan = 0;
  if (T_camerak_cameraj_.empty()) return sum;
  Eigen::Matrix3d R_camerak_cameraj = T_camerak_cameraj_[0].linear();
  ForEachProjected(T_camera_lidar, true, [&](std::size_t i, float x01, float u, float v, float) {
    while (i >= scan_begin_[scan + 1]) R_camerak_cameraj = T_camerak_cameraj_[++scan].linear();
    // Image gradient of the bilinear interpolant Sample(u, v) (per pixel).
    const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
    const double fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
    const float* row0 = image_.ptr<float>(v0) + u0;
    const float* row1 = image_.ptr<float>(v0 + 1) + u0;
    const double y01 = Sample(u, v);
    const double dcost_dy = dcost.SampleDerivative(x01, static_cast<float>(y01));
    if (dcost_dy == 0.0) return;
    const Eigen::RowVector2d dy_duv((1.0 - fv) * (row0[1] - row0[0]) + fv * (row1[1] - row1[0]),
                                    (1.0 - fu) * (row1[0] - row0[0]) + fu * (row1[1] - row0[1]));
    // p_cameraj = T_camera_lidar * x; the swathe point in the image frame k: p = R_kj p_cameraj + t_kj.
    const Eigen::Vector3d p_cameraj = T_camera_lidar * Eigen::Vector3d(x_[i], y_[i], z_[i]);
    const Eigen::Vector3d p = T_camerak_cameraj_[scan] * p_cameraj;
    // dp_cameraj/ddelta = [I, -[w]x]: w = p_cameraj for the left twist, the
    // point relative to the pivot for the update about the pivot.
    const Eigen::Vector3d w = update == TransformUpdate::kLeftTwist ? p_cameraj : Eigen::Vector3d(p_cameraj - pivot_camera);
    Eigen::Matrix<double, 3, 6> dp_ddelta;
    dp_ddelta.leftCols<3>() = R_camerak_cameraj;
    dp_ddelta.rightCols<3>() = -R_camerak_cameraj * Skew(w);
    const Eigen::RowVector3d dy_dp = dy_duv * ProjectionJacobian(projection_, p);
    sum += dcost_dy * (dy_dp * dp_ddelta).transpose();
  });
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
