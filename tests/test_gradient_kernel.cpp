// The block-wise B-spline gradient kernel against straightforward references:
// - SceneSwathe::SampleGradientSum (compacted blocks, closed-form projection
//   Jacobians, per-scan sums of g and p x g) against the per-point formula it
//   replaces, written out here: ForEachProjected, a ceres::Jet projection
//   Jacobian, the 3 x 6 matrix dp/ddelta = R_kj [I, -[w]x], all in double;
//   pinhole, radtan and equidistant cameras, both TransformUpdate modes,
//   several poses, NID and -MI, with occlusion; and its two-pass form (samples
//   recorded by AddBSplineSamples) bit for bit;
// - SceneSwathe::AddBSplineSamples (blocks, BSplineAccumulator) gives the
//   B-spline histogram of ForEachProjected + AddBSpline within rounding;
// - CostGradient::SampleDerivatives (batch, padded table) gives exactly
//   CostGradient::SampleDerivative, including clamped and non-finite values
//   and a CostGradient reused for another bin count.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera_kernel.hpp"
#include "core/geometry.hpp"
#include "core/metric.hpp"
#include "core/nelder_mead.hpp"
#include "core/swathe.hpp"
#include "support/random_swathe.hpp"

namespace scenecal {
namespace {

using test::TestSwathe;

// A swathe of 4 random scans over smooth structure plus noise (image gradients of every size).
TestSwathe MakeSwathe(CameraModelKind kind, std::uint32_t seed) {
  const CameraModel camera = test::MakeKernelTestCamera(kind, 262.0, 258.0);
  cv::Mat noise(camera.height, camera.width, CV_32FC1), image;
  cv::randu(noise, 0.0f, 1.0f);
  cv::GaussianBlur(noise, image, cv::Size(0, 0), 3.0);
  image = 0.7 * image + 0.3 * noise;
  test::RandomSwatheSpec spec;
  spec.scans = 4;
  spec.first_scan_points = 900;
  spec.scan_points_step = 113;
  spec.spread_x = 0.8f;
  spec.spread_y = 0.65f;
  return test::MakeRandomSwathe(camera, image, seed, spec);
}

// d(u, v) / d(p_camera) with ceres::Jet through the camera_kernel templates (an independent derivative of the projection).
Eigen::Matrix<double, 2, 3> ReferenceProjectionJacobian(const ProjectionParams& params, const Eigen::Vector3d& p) {
  using Jet = ceres::Jet<double, 2>;
  const double inverse_z = 1.0 / p.z();
  const Jet xn(p.x() * inverse_z, 0), yn(p.y() * inverse_z, 1);
  Jet xd = xn, yd = yn;
  if (params.kind == CameraModelKind::kRadTan) {
    const Jet k[5] = {Jet(params.k[0]), Jet(params.k[1]), Jet(params.k[2]), Jet(params.k[3]), Jet(params.k[4])};
    camera_detail::DistortRadTan(k, xn, yn, &xd, &yd);
  } else if (params.kind == CameraModelKind::kEquidistant) {
    const Jet k[4] = {Jet(params.k[0]), Jet(params.k[1]), Jet(params.k[2]), Jet(params.k[3])};
    const Jet r = ceres::sqrt(xn * xn + yn * yn + Jet(1e-300));
    const Jet scale = camera_detail::EquidistantScale(k, r, ceres::atan(r));
    xd = xn * scale;
    yd = yn * scale;
  }
  Eigen::Matrix2d d_distorted_d_normalised;
  d_distorted_d_normalised << xd.v[0], xd.v[1], yd.v[0], yd.v[1];
  Eigen::Matrix<double, 2, 3> d_normalised_d_p;
  d_normalised_d_p << inverse_z, 0.0, -p.x() * inverse_z * inverse_z, 0.0, inverse_z, -p.y() * inverse_z * inverse_z;
  return Eigen::Vector2d(params.fx, params.fy).asDiagonal() * d_distorted_d_normalised * d_normalised_d_p;
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

// The lidar points of t's scans in swathe order, as Build keeps them (within
// the range limits, scan by scan, Build's test term for term); *scan_of_point
// gets each one's scan.
std::vector<Eigen::Vector3d> SwathePoints(const TestSwathe& t, std::vector<std::size_t>* scan_of_point) {
  std::vector<Eigen::Vector3d> points;
  scan_of_point->clear();
  const SwatheOptions limits;
  for (std::size_t s = 0; s < t.scans.size(); ++s) {
    for (const LidarPoint& p : t.scans[s].points) {
      const double range2 = static_cast<double>(p.x) * p.x + static_cast<double>(p.y) * p.y +
                            static_cast<double>(p.z) * p.z;
      if (range2 < limits.min_range_m * limits.min_range_m || range2 > limits.max_range_m * limits.max_range_m)
        continue;
      points.emplace_back(p.x, p.y, p.z);
      scan_of_point->push_back(s);
    }
  }
  return points;
}

// T_camerak_cameraj of MakeSwathe's scans: with T_base_camera = identity, Build's
// T_camera_base * T_basek_basej * T_base_camera is each scan's pose itself.
std::vector<Eigen::Isometry3d> SwatheScanPoses(const TestSwathe& t) {
  std::vector<Eigen::Isometry3d> T_camerak_cameraj;
  for (int j = 0; j < static_cast<int>(t.scans.size()); ++j) T_camerak_cameraj.push_back(test::RandomSwatheScanPose(j));
  return T_camerak_cameraj;
}

// The per-point reference of SampleGradientSum. The swathe's scans and their
// poses are those of MakeSwathe: the test rebuilds T_camerak_cameraj the way
// SceneSwathe::Build does (T_base_camera = identity here).
Vector6d ReferenceGradientSum(const TestSwathe& t, const std::vector<Eigen::Isometry3d>& T_camerak_cameraj,
                              const Eigen::Isometry3d& T_camera_lidar, TransformUpdate update,
                              const Eigen::Vector3d& pivot_source, const CostGradient& dcost) {
  const SceneSwathe& swathe = t.swathe;
  const ProjectionParams params = MakeProjectionParams(t.camera.model, 0.5, SwatheOptions{}.min_depth_m);
  std::vector<std::size_t> scan_of_point;
  const std::vector<Eigen::Vector3d> points = SwathePoints(t, &scan_of_point);
  EXPECT_EQ(points.size(), swathe.PointCount());
  const cv::Mat& image = swathe.Image();
  const Eigen::Vector3d pivot_camera = T_camera_lidar * pivot_source;
  Vector6d sum = Vector6d::Zero();
  swathe.ForEachProjected(T_camera_lidar, true, [&](std::size_t i, float x01, float u, float v, float) {
    const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
    const double fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
    const float* row0 = image.ptr<float>(v0) + u0;
    const float* row1 = image.ptr<float>(v0 + 1) + u0;
    const double dcost_dy = dcost.SampleDerivative(x01, swathe.Sample(u, v));
    const Eigen::RowVector2d dy_duv((1.0 - fv) * (row0[1] - row0[0]) + fv * (row1[1] - row1[0]),
                                    (1.0 - fu) * (row1[0] - row0[0]) + fu * (row1[1] - row0[1]));
    const Eigen::Isometry3d& T_kj = T_camerak_cameraj[scan_of_point[i]];
    const Eigen::Vector3d p_cameraj = T_camera_lidar * points[i];
    const Eigen::Vector3d p = T_kj * p_cameraj;
    const Eigen::Vector3d w = update == TransformUpdate::kLeftTwist ? p_cameraj : Eigen::Vector3d(p_cameraj - pivot_camera);
    Eigen::Matrix<double, 3, 6> dp_ddelta;
    dp_ddelta.leftCols<3>() = T_kj.linear();
    dp_ddelta.rightCols<3>() = -T_kj.linear() * Skew(w);
    const Eigen::RowVector3d dy_dp = dy_duv * ReferenceProjectionJacobian(params, p);
    sum += dcost_dy * (dy_dp * dp_ddelta).transpose();
  });
  return sum;
}

CostGradient GradientAt(const SceneSwathe& swathe, const Eigen::Isometry3d& T, const HistogramOptions& options,
                        MetricKind metric, std::size_t* samples) {
  JointHistogram histogram(options);
  const SceneSwathe::BilinearSampler sample = swathe.Sampler();
  swathe.ForEachProjected(T, true, [&](std::size_t, float x01, float u, float v, float) {
    histogram.AddBSpline(x01, sample(u, v));
  });
  *samples = histogram.Samples();
  CostGradient dcost;
  dcost.Compute(histogram, metric);
  return dcost;
}

std::vector<Eigen::Isometry3d> TestPoses() {
  std::vector<Eigen::Isometry3d> poses = {Eigen::Isometry3d::Identity()};
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int i = 0; i < 4; ++i) {
    Vector6d delta;
    for (int k = 0; k < 6; ++k) delta(k) = noise(rng) * (k < 3 ? 0.1 : RadiansFromDegrees(3.0));
    poses.push_back(ExpSE3(delta));
  }
  return poses;
}

TEST(GradientKernel, SampleGradientSumMatchesThePerPointReference) {
  double worst = 0.0;
  int compared = 0;
  for (const CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
    TestSwathe t = MakeSwathe(kind, 17u + static_cast<std::uint32_t>(kind));
    // Some points hidden: the kernel must use the same visible set as ForEachProjected.
    ASSERT_GT(t.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), SwatheOptions{}), 1000u);
    ASSERT_LT(t.swathe.VisibleCount(), t.swathe.PointCount());
    const std::vector<Eigen::Isometry3d> T_camerak_cameraj = SwatheScanPoses(t);
    HistogramOptions options;
    options.binning = Binning::kBSpline;
    options.reflectance_bins = 24;
    options.intensity_bins = 32;
    for (const MetricKind metric : {MetricKind::kNid, MetricKind::kMi}) {
      for (const Eigen::Isometry3d& T : TestPoses()) {
        std::size_t samples = 0;
        const CostGradient dcost = GradientAt(t.swathe, T, options, metric, &samples);
        ASSERT_GT(samples, 500u);
        // The two-pass form of PairCost: samples recorded with the histogram.
        JointHistogram recorded_histogram(options);
        SceneSwathe::GradientSamples record;
        EXPECT_EQ(t.swathe.AddBSplineSamples(T, &recorded_histogram, &record), samples);
        EXPECT_EQ(record.count, samples);
        for (const TransformUpdate update : {TransformUpdate::kAboutSourcePoint, TransformUpdate::kLeftTwist}) {
          const Eigen::Vector3d pivot(0.4, -0.7, 2.5);
          const Vector6d reference = ReferenceGradientSum(t, T_camerak_cameraj, T, update, pivot, dcost);
          const Vector6d fast = t.swathe.SampleGradientSum(T, update, pivot, dcost);
          ASSERT_GT(reference.norm(), 0.0);
          const double relative = (fast - reference).norm() / reference.norm();
          EXPECT_LT(relative, 1e-6) << "camera model " << static_cast<int>(kind) << ", metric "
                                    << MetricKindName(metric) << "\nfast:      " << fast.transpose()
                                    << "\nreference: " << reference.transpose();
          worst = std::max(worst, relative);
          // Bit for bit: the same blocks, samples and sums.
          EXPECT_EQ(t.swathe.SampleGradientSum(record, T, update, pivot, dcost), fast);
          // A record that does not fit the swathe: the self-contained pass.
          EXPECT_EQ(t.swathe.SampleGradientSum(SceneSwathe::GradientSamples{}, T, update, pivot, dcost), fast);
          ++compared;
        }
      }
    }
  }
  EXPECT_EQ(compared, 3 * 2 * 5 * 2);
  RecordProperty("worst_relative_difference", std::to_string(worst));
  std::printf("worst relative difference over %d cases: %.3g\n", compared, worst);
}

// SceneSwathe::AlignmentInformation against its definition written out per point: the central-difference
// image gradient, the pinhole Jacobian by ceres::Jet, dp/ddelta = R_kj [I, -[w]x] with w the point about the
// lidar origin, weighted by the reflectance steps to the scan neighbours.
TEST(GradientKernel, AlignmentInformationMatchesThePerPointReference) {
  TestSwathe t = MakeSwathe(CameraModelKind::kPinhole, 29u);
  ASSERT_GT(t.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), SwatheOptions{}), 1000u);
  const std::vector<Eigen::Isometry3d> T_camerak_cameraj = SwatheScanPoses(t);
  const ProjectionParams params = MakeProjectionParams(t.camera.model, 0.5, SwatheOptions{}.min_depth_m);
  std::vector<std::size_t> scan_of_point;
  const std::vector<Eigen::Vector3d> points = SwathePoints(t, &scan_of_point);
  ASSERT_EQ(points.size(), t.swathe.PointCount());
  const std::span<const float> reflectance = t.swathe.Points().reflectance01;
  const cv::Mat& image = t.swathe.Image();
  for (const Eigen::Isometry3d& T : TestPoses()) {
    Matrix6d reference = Matrix6d::Zero();
    double reference_weight = 0.0;  // sum of contrast x |image gradient|^2
    t.swathe.ForEachProjected(T, true, [&](std::size_t i, float, float u, float v, float) {
      if (!(u >= 1.0f && u < image.cols - 2.0f && v >= 1.0f && v < image.rows - 2.0f)) return;
      double contrast = 0.0;
      if (i > 0 && scan_of_point[i - 1] == scan_of_point[i]) contrast += std::abs(reflectance[i] - reflectance[i - 1]);
      if (i + 1 < points.size() && scan_of_point[i + 1] == scan_of_point[i])
        contrast += std::abs(reflectance[i + 1] - reflectance[i]);
      const Eigen::RowVector2d di_duv(0.5 * (t.swathe.Sample(u + 1.0f, v) - t.swathe.Sample(u - 1.0f, v)),
                                      0.5 * (t.swathe.Sample(u, v + 1.0f) - t.swathe.Sample(u, v - 1.0f)));
      const Eigen::Isometry3d& T_kj = T_camerak_cameraj[scan_of_point[i]];
      const Eigen::Vector3d w = T.linear() * points[i];  // about the lidar origin, camera axes
      const Eigen::Vector3d p = T_kj * (T * points[i]);
      Eigen::Matrix<double, 3, 6> dp_ddelta;
      dp_ddelta.leftCols<3>() = T_kj.linear();
      dp_ddelta.rightCols<3>() = -T_kj.linear() * Skew(w);
      const Eigen::Matrix<double, 1, 6> j = di_duv * ReferenceProjectionJacobian(params, p) * dp_ddelta;
      reference += contrast * j.transpose() * j;
      reference_weight += contrast * di_duv.squaredNorm();
    });
    double weight = -1.0;
    const Matrix6d fast = t.swathe.AlignmentInformation(T, &weight);
    ASSERT_GT(reference.norm(), 0.0);
    EXPECT_NEAR(weight, reference_weight, 1e-4 * reference_weight);  // float projection, as the matrix
    EXPECT_LT((fast - reference).norm() / reference.norm(), 1e-4) << "fast:\n" << fast << "\nreference:\n" << reference;
  }
}

TEST(GradientKernel, AddBSplineSamplesGivesTheVisitorHistogram) {
  int compared = 0;
  for (const CameraModelKind kind : {CameraModelKind::kPinhole, CameraModelKind::kRadTan, CameraModelKind::kEquidistant}) {
    TestSwathe t = MakeSwathe(kind, 29u + static_cast<std::uint32_t>(kind));
    t.swathe.RefreshVisibility(Eigen::Isometry3d::Identity(), SwatheOptions{});
    for (const auto& [nx, ny] : {std::pair{32, 32}, std::pair{5, 48}, std::pair{2, 3}}) {
      HistogramOptions options;
      options.binning = Binning::kBSpline;
      options.reflectance_bins = nx;
      options.intensity_bins = ny;
      for (const Eigen::Isometry3d& T : TestPoses()) {
        JointHistogram expected(options), batch(options);
        const SceneSwathe::BilinearSampler sample = t.swathe.Sampler();
        t.swathe.ForEachProjected(T, true, [&](std::size_t, float x01, float u, float v, float) {
          expected.AddBSpline(x01, sample(u, v));
        });
        const std::size_t added = t.swathe.AddBSplineSamples(T, &batch);
        ASSERT_GT(added, 500u);
        EXPECT_EQ(added, expected.Samples());
        EXPECT_EQ(batch.Samples(), expected.Samples());
        // Within rounding: the accumulator sums in another order.
        double worst = 0.0;
        for (std::size_t i = 0; i < expected.Weights().size(); ++i)
          worst = std::max(worst, std::abs(batch.Weights()[i] - expected.Weights()[i]));
        EXPECT_LT(worst, 1e-12 * static_cast<double>(added)) << nx << " x " << ny << " bins, camera model "
                                                               << static_cast<int>(kind);
        EXPECT_GT(expected.TotalWeight(), 0.0);
        // The gradient pass's fill (recording the samples) gives the value pass's weights bit for bit: a
        // solver sees the same cost with and without the gradient.
        JointHistogram recorded(options);
        SceneSwathe::GradientSamples record;
        EXPECT_EQ(t.swathe.AddBSplineSamples(T, &recorded, &record), added);
        int differing = 0;
        for (std::size_t i = 0; i < expected.Weights().size(); ++i)
          differing += !(recorded.Weights()[i] == batch.Weights()[i]);
        EXPECT_EQ(differing, 0) << nx << " x " << ny << " bins, camera model " << static_cast<int>(kind);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 3 * 3 * 5);
}

TEST(GradientKernel, HardBinningGivesZero) {
  TestSwathe t = MakeSwathe(CameraModelKind::kRadTan, 3u);
  HistogramOptions options;  // hard
  JointHistogram histogram(options);
  const SceneSwathe::BilinearSampler sample = t.swathe.Sampler();
  t.swathe.ForEachProjected(Eigen::Isometry3d::Identity(), true, [&](std::size_t, float x01, float u, float v, float) {
    histogram.Add(x01, sample(u, v));
  });
  CostGradient dcost;
  dcost.Compute(histogram, MetricKind::kNid);
  EXPECT_EQ(t.swathe.SampleGradientSum(Eigen::Isometry3d::Identity(), TransformUpdate::kLeftTwist,
                                       Eigen::Vector3d::Zero(), dcost),
            Vector6d::Zero());
}

TEST(GradientKernel, SampleDerivativesEqualSampleDerivative) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> value(-0.1f, 1.1f);
  CostGradient dcost;
  // Reused across bin counts (the padded table must follow).
  for (const auto& [nx, ny] : {std::pair{32, 32}, std::pair{7, 40}, std::pair{2, 2}, std::pair{40, 3}}) {
    HistogramOptions options;
    options.binning = Binning::kBSpline;
    options.reflectance_bins = nx;
    options.intensity_bins = ny;
    JointHistogram histogram(options);
    std::vector<float> x01, y01;
    for (int k = 0; k < 3000; ++k) {
      const float x = value(rng);
      x01.push_back(x);
      y01.push_back(std::clamp(0.6f * x + 0.4f * value(rng), -0.05f, 1.05f));
      histogram.Add(x01.back(), y01.back());
    }
    // Edges, exact bin boundaries and non-finite values.
    for (const float special : {0.0f, 1.0f, -0.0f, 0.5f, 1.0f / static_cast<float>(ny), std::nextafter(1.0f, 0.0f),
                                std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                                -std::numeric_limits<float>::infinity()}) {
      x01.push_back(special);
      y01.push_back(0.3f);
      x01.push_back(0.3f);
      y01.push_back(special);
    }
    dcost.Compute(histogram, MetricKind::kNid);
    std::vector<double> batch(x01.size(), -1.0);
    dcost.SampleDerivatives(x01.data(), y01.data(), x01.size(), batch.data());
    int differing = 0, nonzero = 0;
    for (std::size_t k = 0; k < x01.size(); ++k) {
      const double single = dcost.SampleDerivative(x01[k], y01[k]);
      differing += !(batch[k] == single);
      nonzero += single != 0.0;
    }
    EXPECT_EQ(differing, 0) << nx << " x " << ny << " bins";
    EXPECT_GT(nonzero, 1000);
  }
}

}  // namespace
}  // namespace scenecal
