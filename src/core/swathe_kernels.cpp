#include "core/swathe.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>

namespace scenecal {

namespace {

// Projects a block of points with the camera model kKind (pinhole or radtan):
// the loop ProjectAnyBlock vectorises.
template <CameraModelKind kKind>
inline void ProjectBlock(const ProjectionParams& params, const Eigen::Matrix<float, 3, 4>& m,
                         const float* __restrict x, const float* __restrict y, const float* __restrict z,
                         int count, float* __restrict u_out, float* __restrict v_out, float* __restrict depth_out,
                         std::int32_t* __restrict accepted) {
  const float m00 = m(0, 0), m01 = m(0, 1), m02 = m(0, 2), m03 = m(0, 3);
  const float m10 = m(1, 0), m11 = m(1, 1), m12 = m(1, 2), m13 = m(1, 3);
  const float m20 = m(2, 0), m21 = m(2, 1), m22 = m(2, 2), m23 = m(2, 3);
  const float fx = params.fx, fy = params.fy, cx = params.cx, cy = params.cy;
  const float u_min = params.u_min, u_max = params.u_max, v_min = params.v_min, v_max = params.v_max;
  const float min_depth = params.min_depth, limit = params.monotonic_limit_squared;
  const float k0 = params.k[0], k1 = params.k[1], k2 = params.k[2], k3 = params.k[3], k4 = params.k[4];
  for (int k = 0; k < count; ++k) {
    const float px = m00 * x[k] + m01 * y[k] + m02 * z[k] + m03;
    const float py = m10 * x[k] + m11 * y[k] + m12 * z[k] + m13;
    const float pz = m20 * x[k] + m21 * y[k] + m22 * z[k] + m23;
    // No guard on the division: points with pz <= min_depth (inf/NaN pixels) are rejected below.
    const float inverse_z = 1.0f / pz;
    float xn = px * inverse_z;
    float yn = py * inverse_z;
    bool in_range = true;
    if constexpr (kKind == CameraModelKind::kRadTan) {
      const float r2 = xn * xn + yn * yn;
      in_range = r2 < limit;
      // camera_detail::DistortRadTan, written out so the loop stays branch-free.
      const float radial = 1.0f + r2 * (k0 + r2 * (k1 + r2 * k4));
      const float xy2 = 2.0f * xn * yn;
      const float xd = xn * radial + k2 * xy2 + k3 * (r2 + 2.0f * xn * xn);
      const float yd = yn * radial + k2 * (r2 + 2.0f * yn * yn) + k3 * xy2;
      xn = xd;
      yn = yd;
    }
    const float u = fx * xn + cx;
    const float v = fy * yn + cy;
    u_out[k] = u;
    v_out[k] = v;
    depth_out[k] = pz;
    // Non-short-circuit & keeps the loop free of branches (vectorisable).
    // (The visibility mask, bytes, is applied in a separate loop: mixing it in here would
    // make the vectoriser process 16 or 32 points per iteration and spill registers.)
    accepted[k] = (pz > min_depth) & in_range & (u >= u_min) & (u < u_max) & (v >= v_min) & (v < v_max);
  }
}

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

}  // namespace

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

// True when every value is finite and within +-kBoundedValueLimit. (A loop
// the compiler vectorises: cv::checkRange took ~1 % of a calibration.)
bool AllBounded(std::span<const float> values) {
  int outside = 0;
  // NaN compares false: outside.
  for (const float value : values) outside |= static_cast<int>(!(std::abs(value) < kBoundedValueLimit));
  return outside == 0;
}

}  // namespace swathe_detail

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
  std::size_t samples = 0;
  ForEachProjectedBlock(T_camera_lidar, true,
                        [&](std::size_t begin, int count, const float* u, const float* v, const float*,
                            const std::int32_t* accepted) {
                          samples += CountHardBlock(image, stride, u, v, accepted, reflectance01_.data() + begin,
                                                    count, reflectance_bins, intensity_bins, counts);
                        });
  return samples;
}

namespace {

using swathe_detail::kBlock;
using swathe_detail::kPrefetchDistance;

// The accepted points of one projected block, compacted (in point order), with
// what their histogram and gradient terms need.
struct GradientBlock {
  alignas(64) float x01[kBlock], y01[kBlock];  // normalised reflectance and bilinear intensity (as Sample)
  alignas(64) double dy_du[kBlock], dy_dv[kBlock];  // gradient of the bilinear interpolant, per pixel
  alignas(64) double dcost_dy[kBlock];
  alignas(64) float x[kBlock], y[kBlock], z[kBlock];  // lidar frame, metres
  alignas(64) float fraction_u[kBlock], fraction_v[kBlock];
  alignas(64) float top_left[kBlock], top_right[kBlock], bottom_left[kBlock], bottom_right[kBlock];
  std::ptrdiff_t offset[kBlock];  // of the top-left pixel, in floats from the image start
  std::uint16_t index[kBlock];    // of the point in its block
};

// Where GatherBlock writes the compacted samples (a GradientBlock's arrays, or
// a GradientSamples record's, at least count entries each).
struct GatherOutput {
  float* __restrict x01;
  float* __restrict y01;
  double* __restrict dy_du;
  double* __restrict dy_dv;
  std::uint16_t* __restrict index;
};

// Compacts the accepted points of a block (u, v, accepted from ProjectAnyBlock;
// x01 the block's reflectances), reads their four pixels and computes the
// bilinear sample (BilinearSampler's expression term for term: the same y01 as
// ForEachProjected + Sample) and, kWithGradient, its image gradient. Returns
// the number of points.
template <bool kWithGradient>
[[gnu::always_inline]] inline int GatherBlock(const float* __restrict image, std::ptrdiff_t stride,
                                              const float* __restrict u, const float* __restrict v,
                                              const std::int32_t* __restrict accepted, const float* __restrict x01,
                                              int count, GradientBlock* __restrict block, const GatherOutput& out) {
  int n = 0;
  for (int k = 0; k < count; ++k) {
    out.index[n] = static_cast<std::uint16_t>(k);
    n += accepted[k];
  }
  for (int a = 0; a < n; ++a) {
    const int k = out.index[a];
    // Accepted points have u, v >= 0: truncation is floor, as in BilinearSampler.
    const int u0 = static_cast<int>(u[k]), v0 = static_cast<int>(v[k]);
    block->fraction_u[a] = u[k] - static_cast<float>(u0);
    block->fraction_v[a] = v[k] - static_cast<float>(v0);
    block->offset[a] = static_cast<std::ptrdiff_t>(v0) * stride + u0;
    out.x01[a] = x01[k];
  }
  for (int a = 0; a < n; ++a) {
    if (a + kPrefetchDistance < n) {
      const float* ahead = image + block->offset[a + kPrefetchDistance];
      __builtin_prefetch(ahead);
      __builtin_prefetch(ahead + stride);
    }
    const float* row0 = image + block->offset[a];
    const float* row1 = row0 + stride;
    block->top_left[a] = row0[0];
    block->top_right[a] = row0[1];
    block->bottom_left[a] = row1[0];
    block->bottom_right[a] = row1[1];
  }
  for (int a = 0; a < n; ++a) {
    const float fu = block->fraction_u[a], fv = block->fraction_v[a];
    const float tl = block->top_left[a], tr = block->top_right[a];
    const float bl = block->bottom_left[a], br = block->bottom_right[a];
    out.y01[a] = (1.0f - fv) * ((1.0f - fu) * tl + fu * tr) + fv * ((1.0f - fu) * bl + fu * br);
    if constexpr (kWithGradient) {
      const double fu_double = fu, fv_double = fv;
      out.dy_du[a] = (1.0 - fv_double) * static_cast<double>(tr - tl) + fv_double * static_cast<double>(br - bl);
      out.dy_dv[a] = (1.0 - fu_double) * static_cast<double>(bl - tl) + fu_double * static_cast<double>(br - tr);
    }
  }
  return n;
}

// GatherBlock compiled for AVX2 and for baseline x86-64 (no FMA: the same samples).
__attribute__((target_clones("avx2", "default"))) int GatherSampleBlock(
    const float* __restrict image, std::ptrdiff_t stride, const float* __restrict u, const float* __restrict v,
    const std::int32_t* __restrict accepted, const float* __restrict x01, int count, GradientBlock* __restrict block,
    const GatherOutput& out) {
  return GatherBlock<false>(image, stride, u, v, accepted, x01, count, block, out);
}

__attribute__((target_clones("avx2", "default"))) int GatherGradientBlock(
    const float* __restrict image, std::ptrdiff_t stride, const float* __restrict u, const float* __restrict v,
    const std::int32_t* __restrict accepted, const float* __restrict x01, int count, GradientBlock* __restrict block,
    const GatherOutput& out) {
  return GatherBlock<true>(image, stride, u, v, accepted, x01, count, block, out);
}

GatherOutput BlockOutput(GradientBlock* block) {
  return {block->x01, block->y01, block->dy_du, block->dy_dv, block->index};
}

// The n points of a block starting at (x, y, z) at the given in-block indices, into block->x, y, z.
void CopyBlockPoints(const float* __restrict x, const float* __restrict y, const float* __restrict z,
                     const std::uint16_t* __restrict index, int n, GradientBlock* __restrict block) {
  for (int a = 0; a < n; ++a) {
    block->x[a] = x[index[a]];
    block->y[a] = y[index[a]];
    block->z[a] = z[index[a]];
  }
}

// Adds, for n points (x, y, z lidar frame, metres; image gradients dy_du,
// dy_dv; dcost_dy), the gradient terms in the image frame k:
//   g = dcost_dy * dy/dp  (p = m * x_lidar, metres; dy/dp = [dy/du dy/dv] d(u, v)/dp)
// to sums[0..2] and p x g to sums[3..5], in double. d(u, v)/dp is the
// closed-form Jacobian of the camera model (pinhole, radtan, equidistant).
template <CameraModelKind kKind>
[[gnu::always_inline]] inline void AccumulateGradientBlock(
    const ProjectionParams& params, const Eigen::Matrix<double, 3, 4>& m, const float* __restrict x_lidar,
    const float* __restrict y_lidar, const float* __restrict z_lidar, const double* __restrict dy_du,
    const double* __restrict dy_dv, const double* __restrict dcost_dy, int n, double* __restrict sums) {
  alignas(64) double terms[6][kBlock];
  const double m00 = m(0, 0), m01 = m(0, 1), m02 = m(0, 2), m03 = m(0, 3);
  const double m10 = m(1, 0), m11 = m(1, 1), m12 = m(1, 2), m13 = m(1, 3);
  const double m20 = m(2, 0), m21 = m(2, 1), m22 = m(2, 2), m23 = m(2, 3);
  const double fx = params.fx, fy = params.fy;
  const double k0 = params.k[0], k1 = params.k[1], k2 = params.k[2], k3 = params.k[3], k4 = params.k[4];
  for (int a = 0; a < n; ++a) {
    const double x = x_lidar[a], y = y_lidar[a], z = z_lidar[a];
    const double px = m00 * x + m01 * y + m02 * z + m03;
    const double py = m10 * x + m11 * y + m12 * z + m13;
    const double pz = m20 * x + m21 * y + m22 * z + m23;
    const double inverse_z = 1.0 / pz;
    const double xn = px * inverse_z, yn = py * inverse_z;
    // d(distorted) / d(normalised), row-major.
    double j00 = 1.0, j01 = 0.0, j10 = 0.0, j11 = 1.0;
    if constexpr (kKind == CameraModelKind::kRadTan) {
      // camera_detail::DistortRadTan differentiated: radial(r2), r2 = xn^2 + yn^2.
      const double r2 = xn * xn + yn * yn;
      const double radial = 1.0 + r2 * (k0 + r2 * (k1 + r2 * k4));
      const double dradial_dr2 = k0 + r2 * (2.0 * k1 + 3.0 * k4 * r2);
      const double cross = 2.0 * xn * yn * dradial_dr2 + 2.0 * k2 * xn + 2.0 * k3 * yn;
      j00 = radial + 2.0 * xn * xn * dradial_dr2 + 2.0 * k2 * yn + 6.0 * k3 * xn;
      j01 = cross;
      j10 = cross;
      j11 = radial + 2.0 * yn * yn * dradial_dr2 + 6.0 * k2 * yn + 2.0 * k3 * xn;
    } else if constexpr (kKind == CameraModelKind::kEquidistant) {
      // distorted = scale(r) * normalised, scale = theta_d(atan r) / r; 1 near the axis (EquidistantScale).
      const double r = std::sqrt(xn * xn + yn * yn);
      if (r > 1e-8) {
        const double theta = std::atan(r);
        const double t2 = theta * theta;
        const double theta_d = theta * (1.0 + t2 * (k0 + t2 * (k1 + t2 * (k2 + t2 * k3))));
        const double dtheta_d_dtheta = 1.0 + t2 * (3.0 * k0 + t2 * (5.0 * k1 + t2 * (7.0 * k2 + t2 * 9.0 * k3)));
        const double scale = theta_d / r;
        const double dscale_dr = (dtheta_d_dtheta / (1.0 + r * r) - scale) / r;
        const double c = dscale_dr / r;  // d scale / d xn = c * xn
        j00 = scale + c * xn * xn;
        j01 = c * xn * yn;
        j10 = j01;
        j11 = scale + c * yn * yn;
      }
    }
    const double dy_dxd = dy_du[a] * fx, dy_dyd = dy_dv[a] * fy;
    const double dy_dxn = dy_dxd * j00 + dy_dyd * j10;
    const double dy_dyn = dy_dxd * j01 + dy_dyd * j11;
    // d(xn, yn)/dp = [1/z 0 -xn/z; 0 1/z -yn/z].
    const double scale = dcost_dy[a] * inverse_z;
    const double gx = scale * dy_dxn, gy = scale * dy_dyn, gz = -scale * (dy_dxn * xn + dy_dyn * yn);
    terms[0][a] = gx;
    terms[1][a] = gy;
    terms[2][a] = gz;
    terms[3][a] = py * gz - pz * gy;
    terms[4][a] = pz * gx - px * gz;
    terms[5][a] = px * gy - py * gx;
  }
  // Four running sums per term (vectorised; a fixed order, so deterministic).
  for (int c = 0; c < 6; ++c) {
    double lanes[4] = {0.0, 0.0, 0.0, 0.0};
    int a = 0;
    for (; a + 4 <= n; a += 4) {
      for (int l = 0; l < 4; ++l) lanes[l] += terms[c][a + l];
    }
    for (; a < n; ++a) lanes[0] += terms[c][a];
    sums[c] += (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
  }
}

__attribute__((target_clones("avx2", "default"))) void AccumulateAnyGradientBlock(
    const ProjectionParams& params, const Eigen::Matrix<double, 3, 4>& m, const GradientBlock& block,
    const double* __restrict dy_du, const double* __restrict dy_dv, int n, double* __restrict sums) {
  switch (params.kind) {
    case CameraModelKind::kPinhole:
      AccumulateGradientBlock<CameraModelKind::kPinhole>(params, m, block.x, block.y, block.z, dy_du, dy_dv,
                                                         block.dcost_dy, n, sums);
      break;
    case CameraModelKind::kRadTan:
      AccumulateGradientBlock<CameraModelKind::kRadTan>(params, m, block.x, block.y, block.z, dy_du, dy_dv,
                                                        block.dcost_dy, n, sums);
      break;
    case CameraModelKind::kEquidistant:
      AccumulateGradientBlock<CameraModelKind::kEquidistant>(params, m, block.x, block.y, block.z, dy_du, dy_dv,
                                                             block.dcost_dy, n, sums);
      break;
  }
}

// Per point (p_cameraj = T_camera_lidar x, p = R_kj p_cameraj + t_kj in the
// image frame k, g = dcost_dy * dy/dp): dp/ddelta = R_kj [I, -[w]x] with w =
// p_cameraj for the left twist and p_cameraj - pivot_camera about the pivot,
// so the point adds a = R_kj^T g to the translation part and w x a =
// R_kj^T ((p - c) x g) to the rotation part, c = T_kj pivot_camera (pivot_camera
// = 0 for the left twist). Per scan, then, the sums of g and p x g in frame k
// (sums[0..2], sums[3..5]) suffice: this adds the scan's part to *gradient.
void AddScanGradient(const Eigen::Isometry3d& T_camerak_cameraj, const Eigen::Vector3d& pivot_camera,
                     const double* sums, Vector6d* gradient) {
  const Eigen::Matrix3d R_camerak_cameraj = T_camerak_cameraj.linear();
  const Eigen::Vector3d c = T_camerak_cameraj * pivot_camera;
  const Eigen::Vector3d g_sum(sums[0], sums[1], sums[2]);
  const Eigen::Vector3d p_cross_g_sum(sums[3], sums[4], sums[5]);
  gradient->head<3>() += R_camerak_cameraj.transpose() * g_sum;
  gradient->tail<3>() += R_camerak_cameraj.transpose() * (p_cross_g_sum - c.cross(g_sum));
}

Eigen::Vector3d PivotInCamera(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                              const Eigen::Vector3d& pivot_source) {
  return update == TransformUpdate::kLeftTwist ? Eigen::Vector3d::Zero()
                                               : Eigen::Vector3d(T_camera_lidar * pivot_source);
}

}  // namespace

std::size_t SceneSwathe::AddBSplineSamples(const Eigen::Isometry3d& T_camera_lidar, JointHistogram* histogram,
                                           GradientSamples* record) const {
  using namespace swathe_detail;
  if (record != nullptr) {
    // Room for every point; grown only (zero-filling is the cost), never shrunk.
    record->count = 0;
    record->block_samples.clear();
    if (record->x01.size() < x_.size()) {
      record->x01.resize(x_.size());
      record->y01.resize(x_.size());
      record->dy_du.resize(x_.size());
      record->dy_dv.resize(x_.size());
      record->index.resize(x_.size());
    }
  }
  if (image_.empty()) return 0;
  const float* const image = image_.ptr<float>();
  const auto stride = static_cast<std::ptrdiff_t>(image_.step1());
  GradientBlock block;
  std::size_t samples = 0;
  thread_local BSplineAccumulator accumulator;
  accumulator.Reset(histogram->ReflectanceBins(), histogram->IntensityBins());
  ForEachProjectedBlock(T_camera_lidar, true, [&](std::size_t begin, int count, const float* u, const float* v,
                                                  const float*, const std::int32_t* accepted) {
    const float* x01 = reflectance01_.data() + begin;
    if (record == nullptr) {
      const int n = GatherSampleBlock(image, stride, u, v, accepted, x01, count, &block, BlockOutput(&block));
      accumulator.Add(block.x01, block.y01, static_cast<std::size_t>(n));
      samples += static_cast<std::size_t>(n);
      return;
    }
    // Straight into the record (samples <= begin: room for the block's points).
    const GatherOutput out = {record->x01.data() + samples, record->y01.data() + samples,
                              record->dy_du.data() + samples, record->dy_dv.data() + samples,
                              record->index.data() + samples};
    const int n = GatherGradientBlock(image, stride, u, v, accepted, x01, count, &block, out);
    accumulator.Add(out.x01, out.y01, static_cast<std::size_t>(n));
    samples += static_cast<std::size_t>(n);
    record->count = samples;
    record->block_samples.push_back(static_cast<std::uint16_t>(n));
  });
  accumulator.AddTo(histogram);
  return samples;
}

Vector6d SceneSwathe::SampleGradientSum(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                                        const Eigen::Vector3d& pivot_source, const CostGradient& dcost) const {
  using namespace swathe_detail;
  Vector6d sum = Vector6d::Zero();
  if (image_.empty() || T_camerak_cameraj_.empty()) return sum;
  const Eigen::Vector3d pivot_camera = PivotInCamera(T_camera_lidar, update, pivot_source);
  const float* const image = image_.ptr<float>();
  const auto stride = static_cast<std::ptrdiff_t>(image_.step1());
  alignas(64) float u[kBlock], v[kBlock], depth[kBlock];
  alignas(64) std::int32_t accepted[kBlock];
  GradientBlock block;
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Isometry3d T_camerak_lidar = T_camerak_cameraj_[scan] * T_camera_lidar;
    const Eigen::Matrix<float, 3, 4> m = T_camerak_lidar.matrix().topRows<3>().cast<float>();
    const Eigen::Matrix<double, 3, 4> m_double = T_camerak_lidar.matrix().topRows<3>();
    double sums[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const std::size_t end = scan_begin_[scan + 1];
    for (std::size_t begin = scan_begin_[scan]; begin < end; begin += kBlock) {
      const int count = static_cast<int>(std::min<std::size_t>(kBlock, end - begin));
      const float *x = x_.data() + begin, *y = y_.data() + begin, *z = z_.data() + begin;
      ProjectAnyBlock(projection_, m, x, y, z, visible_.data() + begin, count, u, v, depth, accepted);
      const int n = GatherGradientBlock(image, stride, u, v, accepted, reflectance01_.data() + begin, count, &block,
                                        BlockOutput(&block));
      if (n == 0) continue;
      CopyBlockPoints(x, y, z, block.index, n, &block);
      dcost.SampleDerivatives(block.x01, block.y01, static_cast<std::size_t>(n), block.dcost_dy);
      AccumulateAnyGradientBlock(projection_, m_double, block, block.dy_du, block.dy_dv, n, sums);
    }
    AddScanGradient(T_camerak_cameraj_[scan], pivot_camera, sums, &sum);
  }
  return sum;
}

Vector6d SceneSwathe::SampleGradientSum(const GradientSamples& samples, const Eigen::Isometry3d& T_camera_lidar,
                                        TransformUpdate update, const Eigen::Vector3d& pivot_source,
                                        const CostGradient& dcost) const {
  using namespace swathe_detail;
  // The record must be of this swathe (its blocks and samples); otherwise the self-contained pass.
  std::size_t blocks = 0;
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan)
    blocks += (scan_begin_[scan + 1] - scan_begin_[scan] + kBlock - 1) / kBlock;
  const std::size_t count = samples.count;
  if (image_.empty() || samples.block_samples.size() != blocks || samples.x01.size() < count ||
      samples.y01.size() < count || samples.dy_du.size() < count || samples.dy_dv.size() < count ||
      samples.index.size() < count)
    return SampleGradientSum(T_camera_lidar, update, pivot_source, dcost);
  Vector6d sum = Vector6d::Zero();
  const Eigen::Vector3d pivot_camera = PivotInCamera(T_camera_lidar, update, pivot_source);
  GradientBlock block;
  std::size_t block_number = 0, first = 0;
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Matrix<double, 3, 4> m_double =
        (T_camerak_cameraj_[scan] * T_camera_lidar).matrix().topRows<3>();
    double sums[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    const std::size_t end = scan_begin_[scan + 1];
    for (std::size_t begin = scan_begin_[scan]; begin < end; begin += kBlock) {
      const int n = samples.block_samples[block_number++];
      if (n == 0) continue;
      if (first + static_cast<std::size_t>(n) > count)
        return SampleGradientSum(T_camera_lidar, update, pivot_source, dcost);
      // The same blocks and data as the self-contained pass: the same sums, bit for bit.
      CopyBlockPoints(x_.data() + begin, y_.data() + begin, z_.data() + begin, samples.index.data() + first, n,
                      &block);
      dcost.SampleDerivatives(samples.x01.data() + first, samples.y01.data() + first, static_cast<std::size_t>(n),
                              block.dcost_dy);
      AccumulateAnyGradientBlock(projection_, m_double, block, samples.dy_du.data() + first,
                                 samples.dy_dv.data() + first, n, sums);
      first += static_cast<std::size_t>(n);
    }
    AddScanGradient(T_camerak_cameraj_[scan], pivot_camera, sums, &sum);
  }
  return sum;
}
}  // namespace scenecal
