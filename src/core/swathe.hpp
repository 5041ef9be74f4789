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
//
// swathe.cpp builds, thins and re-poses the swathe and refreshes visibility;
// swathe_kernels.cpp holds the vectorised evaluation kernels, swathe_motion.cpp
// the odometry drift correction.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera_kernel.hpp"
#include "core/geometry.hpp"
#include "core/metric.hpp"
#include "core/nelder_mead.hpp"
#include "core/normalisation.hpp"
#include "core/rig.hpp"
#include "core/scenes.hpp"
#include "core/swathe_kernels.hpp"
#include "core/swathe_motion.hpp"

namespace scenecal {

// The blurred image of a camera frame, made by the first of the frame's swathes
// that asks for a blur and shared by the others (range bands, the pairs of other
// lidars): the stages move every swathe of a frame to the same blur together.
struct SwatheBlurCache {
  std::mutex mutex;
  double sigma_px = 0.0;  // the blur of `blurred` (pixels, 1-sigma)
  cv::Mat blurred;        // CV_32FC1; empty until a blur is asked for
};

// The images a swathe scores, prepared once per camera frame and shared (not
// copied: swathes only read them) by the swathes built from that frame (range
// bands, the trimming pass, the pairs of every lidar through PreparedImageCache).
struct SwatheImages {
  cv::Mat sharp;  // CV_32FC1, normalised (high-passed when asked): the final, unblurred stages' image
  cv::Mat plain;  // with a high-pass only: the normalised whole image the blurred stages start from
  std::shared_ptr<SwatheBlurCache> blur = std::make_shared<SwatheBlurCache>();

  // From a frame's GreyImage intensity (CV_32FC1 in [0, 1]) with
  // normalisation.intensity (and its high-pass). Empty on an unusable image.
  static SwatheImages Prepare(const cv::Mat& intensity, const NormalisationOptions& normalisation);
};

struct SwatheOptions {
  double min_range_m = 1.0;    // lidar points nearer than this (lidar frame) are dropped (vehicle body, noise)
  double max_range_m = 100.0;  // and farther than this
  double min_depth_m = 0.2;    // camera-frame depth below which a point does not project
  // Z-buffer occlusion test. Cell size in pixels; 0 = automatic (image width / 80, at least 4).
  bool occlusion = true;
  int occlusion_cell_px = 0;
  double occlusion_relative_margin = 0.2;  // hidden if depth > nearest * (1 + relative) + absolute
  double occlusion_absolute_margin_m = 0.3;
  // When > 0, only the points that project at least this many pixels inside
  // the image where the visibility is refreshed are scored until the next
  // refresh, so the set an optimiser run scores stays the same while the
  // estimate moves them by less than this (0 = off: points enter and leave at
  // the border).
  double refresh_border_px = 0.0;
  // When > 0, a blurred (coarse) stage scores every k-th point of a swathe,
  // k = the blur's sigma / this many pixels (rounded down; 0 = every point):
  // within a blur's width the samples say nearly the same. At 8 the push-broom
  // setting's first stage (25.6 px at 1280, k = 3) took half the time an
  // evaluation, but one of 15 starts 30 cm / 10 deg off ran off to 1 m / 22 deg
  // (RobotCar-like world 3; none without it): off by default.
  double blur_px_per_point_stride = 0.0;

  bool IsValid(std::string* why = nullptr) const;
};

// The k of SwatheOptions::blur_px_per_point_stride for a blur of sigma_px.
int PointStrideForBlur(double sigma_px, double blur_px_per_point_stride);

class SceneSwathe {
 public:
  SceneSwathe() = default;

  // What the gradient pass needs of each B-spline sample, recorded by
  // AddBSplineSamples for SampleGradientSum (storage reused across calls).
  struct GradientSamples {
    std::size_t count = 0;                   // samples recorded (the arrays may be longer: reused storage)
    std::vector<float> x01, y01;             // as added to the histogram
    std::vector<double> dy_du, dy_dv;        // image gradient of the bilinear interpolant (per pixel)
    std::vector<std::uint16_t> index;        // of the sample's point in its block
    std::vector<std::uint16_t> block_samples;  // samples per block (scan by scan, swathe_detail::kBlock points)
  };

  // Builds the swathe of `scene` seen by `camera`: scans[i] is the scan at
  // scene.scans[i].t_us (same order and size). `intensity` is the frame's
  // GreyImage intensity (CV_32FC1 in [0, 1]); it is normalised here with
  // normalisation.intensity and reflectances with normalisation.reflectance.
  // A size mismatch leaves an empty swathe (PointCount() == 0).
  static SceneSwathe Build(const Scene& scene, const CameraInfo& camera, const cv::Mat& intensity,
                           const std::vector<const LidarScan*>& scans, const SwatheOptions& options,
                           const NormalisationOptions& normalisation);
  // The same with the frame's images already prepared (SwatheImages::Prepare
  // with the same normalisation), for several swathes of one frame.
  static SceneSwathe Build(const Scene& scene, const CameraInfo& camera, const SwatheImages& images,
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

  // The same bilinear sampling as Sample, on a flat copy of the image's
  // pointer and row stride: hot loops keep these in registers (the compiler
  // cannot, through cv::Mat, once the loop writes to memory).
  struct BilinearSampler {
    const float* data = nullptr;
    std::size_t stride = 0;  // floats per row
    float operator()(float u, float v) const {
      const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
      const float fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
      const float* row0 = data + static_cast<std::size_t>(v0) * stride + u0;
      const float* row1 = row0 + stride;
      return (1.0f - fv) * ((1.0f - fu) * row0[0] + fu * row0[1]) + fv * ((1.0f - fu) * row1[0] + fu * row1[1]);
    }
  };
  BilinearSampler Sampler() const { return {image_.ptr<float>(), image_.step1()}; }

  // Thins the swathe where its points crowd in the image: with the points
  // projected under T_camera_lidar (an estimate, e.g. the initial guess) into
  // square cells of cell_px pixels, a cell holding n > max_points_per_cell
  // points keeps each of them with probability max_points_per_cell / n (a fixed
  // hash of the scene's image time and the point's index: deterministic).
  // Points that do not project into the image grown by margin_px on every side
  // (or lie behind the camera) are dropped; keep margin_px above the pixel
  // motion the optimisation may bring. Far scans of a long swathe land many
  // points on one pixel; thinning them costs little information and makes
  // every evaluation faster. Returns the number of points kept.
  // `camera` is the model the swathe was built with (a size mismatch leaves it whole).
  std::size_t ThinByImageDensity(const CameraModel& camera, const Eigen::Isometry3d& T_camera_lidar, int cell_px,
                                 int max_points_per_cell, double margin_px);

  // Recomputes the visibility mask with the z-buffer at T_camera_lidar; points
  // that do not project at this estimate stay visible. Returns the number of
  // points that project (before hiding).
  std::size_t RefreshVisibility(const Eigen::Isometry3d& T_camera_lidar, const SwatheOptions& options);

  // Analytic gradient for B-spline metrics: the sum over the visible points
  // that project under T_camera_lidar (those of ForEachProjected) of
  // dcost.SampleDerivative(x01, y01) * dy01/ddelta, where y01 is the bilinear
  // intensity and delta the local update of ApplyTransformUpdate(T_camera_lidar,
  // delta, update, pivot_source) at delta = 0 (core/nelder_mead.hpp):
  //   dy01/ddelta = [dY/du dY/dv] (image gradient of the bilinear interpolant)
  //                 * d(u, v)/dp (projection with distortion) * dp/ddelta.
  // `dcost` must come from the histogram of the same samples. Computed block by
  // block (closed-form projection Jacobians, double) and summed per scan in a
  // fixed order: deterministic.
  Vector6d SampleGradientSum(const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                             const Eigen::Vector3d& pivot_source, const CostGradient& dcost) const;
  // The same sum (bit for bit) from the samples AddBSplineSamples recorded at the
  // same T_camera_lidar (a record that does not fit this swathe falls back to the
  // pass above).
  Vector6d SampleGradientSum(const GradientSamples& samples, const Eigen::Isometry3d& T_camera_lidar,
                             TransformUpdate update, const Eigen::Vector3d& pivot_source,
                             const CostGradient& dcost) const;

  // Adds the visible points that project under T_camera_lidar to the histogram
  // with B-spline binning: histogram->AddBSpline(x01, Sample(u, v)) for each
  // point of ForEachProjected (the same samples; the weights equal within
  // rounding, summed in BSplineAccumulator's order), with the windows computed
  // per block in vectorised loops. Returns the number of points added.
  // With record, also records what SampleGradientSum needs of each sample
  // (GradientSamples), so that the gradient pass (after CostGradient::Compute on
  // the histogram) neither projects nor samples the image again.
  std::size_t AddBSplineSamples(const Eigen::Isometry3d& T_camera_lidar, JointHistogram* histogram,
                                GradientSamples* record = nullptr) const;

  // The hard-binned joint histogram of the visible points that project under
  // T_camera_lidar, as integer counts: for each such point,
  //   ++counts[HardBin(x01, reflectance_bins) * intensity_bins + HardBin(Sample(u, v), intensity_bins)]
  // (core/metric.hpp), i.e. exactly the bins of ForEachProjected + Sample + HardBin
  // (the same float arithmetic in the same order, so the same samples), but with the
  // pixel fractions, bilinear weights and bins computed per block in vectorised loops
  // and only the four image reads per point left scalar (the hard NID kernel).
  // counts holds reflectance_bins * intensity_bins entries and is added to, not
  // cleared. Returns the number of points counted. Deterministic, allocation-free.
  std::size_t AddHardCounts(const Eigen::Isometry3d& T_camera_lidar, int reflectance_bins, int intensity_bins,
                            std::uint32_t* counts) const;

  // Number of points that project (visible ones only, counted before a blurred
  // stage's point stride) under T_camera_lidar.
  std::size_t CountProjected(const Eigen::Isometry3d& T_camera_lidar) const;
  // The same count split by scan (ScanCount() entries, in scan order), all
  // points, visible or not: which scans of the swathe reach the image at all.
  std::vector<std::size_t> CountProjectedPerScan(const Eigen::Isometry3d& T_camera_lidar) const;
  // How much the scene constrains the extrinsic (the informative scene
  // choice): sum over the visible points that project under T_camera_lidar of
  //   w * j^T j,  j = [dI/du dI/dv] * d(u, v)/dc * dc/ddelta   (1 x 6),
  // the Gauss-Newton information of aligning the image's edges, where delta =
  // [rho; phi] moves T_camera_lidar (metres and radians, camera axes, rotation
  // about the lidar origin), d(u, v)/dc the pinhole part of the projection,
  // dI/du the image gradient there, and w the reflectance contrast of the
  // point with its neighbours in its scan (a point on a uniform surface
  // informs a multi-modal metric as little as one on a uniform image region).
  // *gradient_weight (optional) gets sum of w * |dI/du dI/dv|^2 over the same
  // points: the information divided by it is the mean, over the edges, of the
  // squared displacement (pixels) normal to the edge per unit of delta.
  Matrix6d AlignmentInformation(const Eigen::Isometry3d& T_camera_lidar, double* gradient_weight = nullptr) const;

  // Sum of the lidar-frame coordinates (metres) of those points; *count gets their number.
  Eigen::Vector3d SumProjectedLidarPoints(const Eigen::Isometry3d& T_camera_lidar, std::size_t* count) const;

  // Gaussian blur of the working image (pixels, 1-sigma); 0 restores the sharp
  // image. For coarse-to-fine smoothing between optimiser runs, never inside one.
  // With an intensity high-pass (NormalisationOptions) the sharp image is the
  // high-passed one and a blur applies to the whole (plain) image.
  // point_stride > 1 also leaves only every point_stride-th point visible
  // (PointStrideForBlur), now and after each RefreshVisibility, until a
  // stride of 1 restores the full mask.
  void SetImageBlur(double sigma_px, int point_stride = 1);

  // Re-poses the scans with the trajectory corrected by `correction`
  // (CorrectSwatheMotion; zero restores the poses as built). Not thread-safe;
  // the visibility mask is kept (refresh it when the estimate has moved).
  void SetMotionCorrection(const SwatheMotionCorrection& correction);
  const SwatheMotionCorrection& MotionCorrection() const { return motion_correction_; }

  const cv::Mat& Image() const { return image_; }

  // The stored points as the kernels read them, in their order (structure of
  // arrays: lidar frame, metres; normalised reflectance; visibility mask): what
  // a benchmark's read-only bound reads.
  struct PointArrays {
    std::span<const float> x, y, z, reflectance01;
    std::span<const std::uint8_t> visible;
  };
  PointArrays Points() const { return {x_, y_, z_, reflectance01_, visible_}; }

 private:
  // The projection loop shared by the kernels: for each block of up to
  // swathe_detail::kBlock points of one scan, ProjectAnyBlock under the scan's
  // precomposed transform, then visit(begin, count, u, v, depth, accepted) with
  // the block's first point index and ProjectAnyBlock's outputs (hidden points
  // rejected when visible_only).
  template <typename BlockVisitor>
  void ForEachProjectedBlock(const Eigen::Isometry3d& T_camera_lidar, bool visible_only, BlockVisitor&& visit) const;

  std::string camera_, lidar_;
  TimeUs image_t_us_ = 0;
  ProjectionParams projection_;
  cv::Mat image_;        // CV_32FC1, normalised; the working image (possibly blurred)
  cv::Mat image_sharp_;  // CV_32FC1, normalised, never blurred (high-passed when asked)
  cv::Mat image_plain_;  // with a high-pass only: the normalised image the blurred stages start from
  double blur_sigma_px_ = 0.0;  // the blur of image_ (pixels, 1-sigma; 0 = sharp)
  std::shared_ptr<SwatheBlurCache> blur_cache_;  // the frame's, shared with its other swathes
  bool image_constant_ = false;
  bool reflectance_constant_ = false;
  // Image and reflectances finite and bounded (AddHardCounts' fast path needs it).
  bool values_bounded_ = false;
  // Points in the lidar frame (metres) and normalised reflectance, SoA.
  std::vector<float> x_, y_, z_, reflectance01_;
  std::vector<std::uint8_t> visible_;
  int point_stride_ = 1;                          // SetImageBlur's stride
  std::vector<std::uint8_t> unstrided_visible_;  // visible_ before the stride (empty at stride 1)
  void ApplyPointStride();
  std::size_t RefreshVisibilityMask(const Eigen::Isometry3d& T_camera_lidar, const SwatheOptions& options);
  std::vector<std::size_t> scan_begin_;  // points of scan i: [scan_begin_[i], scan_begin_[i + 1])
  std::vector<Eigen::Isometry3d> T_camerak_cameraj_;
  // T_camerak_cameraj_ = T_camera_base * T_basek_basej * T_base_camera, one per scan.
  void ComposeScanPoses(const std::vector<Eigen::Isometry3d>& T_basek_basej);

  // As built from the trajectory, for SetMotionCorrection (one per scan, as T_camerak_cameraj_).
  std::vector<TimeUs> scan_t_us_;
  std::vector<Eigen::Isometry3d> T_basek_basej_;
  Eigen::Isometry3d T_base_camera_ = Eigen::Isometry3d::Identity();
  SwatheMotionCorrection motion_correction_;
};

template <typename BlockVisitor>
void SceneSwathe::ForEachProjectedBlock(const Eigen::Isometry3d& T_camera_lidar, bool visible_only,
                                        BlockVisitor&& visit) const {
  using namespace swathe_detail;
  alignas(64) float u[kBlock], v[kBlock], depth[kBlock];
  alignas(64) std::int32_t accepted[kBlock];
  alignas(64) std::uint8_t all_visible[kBlock];
  if (!visible_only) std::fill(std::begin(all_visible), std::end(all_visible), std::uint8_t{1});
  for (std::size_t scan = 0; scan < T_camerak_cameraj_.size(); ++scan) {
    const Eigen::Matrix<float, 3, 4> m =
        (T_camerak_cameraj_[scan] * T_camera_lidar).matrix().topRows<3>().cast<float>();
    const std::size_t end = scan_begin_[scan + 1];
    for (std::size_t begin = scan_begin_[scan]; begin < end; begin += kBlock) {
      const int count = static_cast<int>(std::min<std::size_t>(kBlock, end - begin));
      const std::uint8_t* visible = visible_only ? visible_.data() + begin : all_visible;
      ProjectAnyBlock(projection_, m, x_.data() + begin, y_.data() + begin, z_.data() + begin, visible, count, u, v,
                      depth, accepted);
      visit(begin, count, u, v, depth, accepted);
    }
  }
}

template <typename Visitor>
void SceneSwathe::ForEachProjected(const Eigen::Isometry3d& T_camera_lidar, bool visible_only,
                                   Visitor&& visit) const {
  using namespace swathe_detail;
  const float* const image = image_.empty() ? nullptr : image_.ptr<float>();
  const std::size_t stride = image_.step1();
  const float* const reflectance01 = reflectance01_.data();
  ForEachProjectedBlock(T_camera_lidar, visible_only,
                        [&](std::size_t begin, int count, const float* u, const float* v, const float* depth,
                            const std::int32_t* accepted) {
                          std::uint16_t index[kBlock];
                          int accepted_count = 0;
                          for (int k = 0; k < count; ++k) {
                            index[accepted_count] = static_cast<std::uint16_t>(k);
                            accepted_count += accepted[k];
                          }
                          for (int a = 0; a < accepted_count; ++a) {
                            if (a + kPrefetchDistance < accepted_count) {
                              const int ahead = index[a + kPrefetchDistance];
                              // Through int: float -> size_t conversion costs a compare and branch per point on x86-64.
                              const float* row = image +
                                                 static_cast<std::ptrdiff_t>(static_cast<int>(v[ahead])) *
                                                     static_cast<std::ptrdiff_t>(stride) +
                                                 static_cast<int>(u[ahead]);
                              __builtin_prefetch(row);
                              __builtin_prefetch(row + stride);
                            }
                            const int k = index[a];
                            visit(begin + static_cast<std::size_t>(k),
                                  reflectance01[begin + static_cast<std::size_t>(k)], u[k], v[k], depth[k]);
                          }
                        });
}

}  // namespace scenecal
