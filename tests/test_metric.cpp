// Joint histograms, NID / MI against hand-computed values, B-spline binning,
// the analytic gradient, and the reflectance / intensity normalisation.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/metric.hpp"
#include "core/normalisation.hpp"

namespace scenecal {
namespace {

HistogramOptions Options(int bins_x, int bins_y, Binning binning) {
  HistogramOptions options;
  options.reflectance_bins = bins_x;
  options.intensity_bins = bins_y;
  options.binning = binning;
  return options;
}

// The centre of bin b of `bins` in [0, 1].
float Centre(int b, int bins) { return (static_cast<float>(b) + 0.5f) / static_cast<float>(bins); }

// Adds `count` samples to bin (i, j) of a hard histogram.
void AddCount(JointHistogram* histogram, int i, int j, int count) {
  for (int k = 0; k < count; ++k) {
    histogram->Add(Centre(i, histogram->ReflectanceBins()), Centre(j, histogram->IntensityBins()));
  }
}

InformationMeasures Measure(const std::vector<float>& x, const std::vector<float>& y, const HistogramOptions& options) {
  JointHistogram histogram(options);
  for (std::size_t k = 0; k < x.size(); ++k) histogram.Add(x[k], y[k]);
  return ComputeInformation(histogram);
}

TEST(Metric, NamesParseAndOptionsValidate) {
  EXPECT_EQ(ParseMetricKind("nid"), MetricKind::kNid);
  EXPECT_EQ(ParseMetricKind("mi"), MetricKind::kMi);
  EXPECT_FALSE(ParseMetricKind("NID?").has_value());
  for (MetricKind kind : {MetricKind::kNid, MetricKind::kMi}) EXPECT_EQ(ParseMetricKind(MetricKindName(kind)), kind);
  for (Binning binning : {Binning::kHard, Binning::kBSpline}) EXPECT_EQ(ParseBinning(BinningName(binning)), binning);
  EXPECT_FALSE(ParseBinning("soft").has_value());

  std::string why;
  EXPECT_TRUE(HistogramOptions{}.IsValid(&why)) << why;
  EXPECT_FALSE(Options(1, 32, Binning::kHard).IsValid(&why));
  EXPECT_NE(why.find("reflectance_bins"), std::string::npos) << why;
  EXPECT_FALSE(Options(32, HistogramOptions::kMaxBins + 1, Binning::kHard).IsValid(&why));
  EXPECT_NE(why.find("intensity_bins"), std::string::npos) << why;
}

TEST(Metric, KnownTwoByTwoTable) {
  // Counts (rows x = reflectance bin, columns y = intensity bin):
  //   [[2, 1],
  //    [0, 1]]   N = 4
  // p(x) = (3/4, 1/4), p(y) = (1/2, 1/2), p(x,y) = (1/2, 1/4, 0, 1/4).
  // H(X)   = -(3/4 ln 3/4 + 1/4 ln 1/4)  = 0.562335144618...
  // H(Y)   = ln 2                         = 0.693147180559...
  // H(X,Y) = 1/2 ln 2 + 2 * 1/4 ln 4      = 3/2 ln 2 = 1.039720770839...
  // MI     = H(X) + H(Y) - H(X,Y)         = 0.215761554338...
  // NID    = (H(X,Y) - MI) / H(X,Y)       = 0.792481250360...
  JointHistogram histogram(Options(2, 2, Binning::kHard));
  AddCount(&histogram, 0, 0, 2);
  AddCount(&histogram, 0, 1, 1);
  AddCount(&histogram, 1, 1, 1);
  ASSERT_EQ(histogram.Weight(0, 0), 2.0);
  ASSERT_EQ(histogram.Weight(1, 0), 0.0);
  const InformationMeasures m = ComputeInformation(histogram);
  const double hx = -(0.75 * std::log(0.75) + 0.25 * std::log(0.25));
  const double hy = std::log(2.0);
  const double hxy = 1.5 * std::log(2.0);
  EXPECT_NEAR(m.entropy_x, hx, 1e-14);
  EXPECT_NEAR(m.entropy_x, 0.562335144618, 1e-11);
  EXPECT_NEAR(m.entropy_y, hy, 1e-14);
  EXPECT_NEAR(m.joint_entropy, hxy, 1e-14);
  EXPECT_NEAR(m.mutual_information, 0.215761554338, 1e-11);
  EXPECT_NEAR(m.nid, 0.792481250360, 1e-11);
  EXPECT_EQ(m.samples, 4u);
  EXPECT_NEAR(CostValue(m, MetricKind::kNid), m.nid, 0.0);
  EXPECT_NEAR(CostValue(m, MetricKind::kMi), -m.mutual_information, 0.0);
}

TEST(Metric, KnownThreeByTwoTable) {
  // Counts [[1, 1], [2, 0], [0, 4]], N = 8.
  // p(x) = (1/4, 1/4, 1/2): H(X) = 2 * 1/4 ln 4 + 1/2 ln 2 = 3/2 ln 2
  // p(y) = (3/8, 5/8):      H(Y) = -(3/8 ln 3/8 + 5/8 ln 5/8) = 0.661563238...
  // p(x,y) = (1/8, 1/8, 1/4, 0, 0, 1/2): H(X,Y) = 2/8 ln 8 + 1/4 ln 4 + 1/2 ln 2 = 7/4 ln 2
  // MI = 3/2 ln 2 + H(Y) - 7/4 ln 2 = H(Y) - 1/4 ln 2 = 0.488276443...
  // NID = 1 - MI / H(X,Y) = 0.597466284...
  JointHistogram histogram(Options(3, 2, Binning::kHard));
  AddCount(&histogram, 0, 0, 1);
  AddCount(&histogram, 0, 1, 1);
  AddCount(&histogram, 1, 0, 2);
  AddCount(&histogram, 2, 1, 4);
  const InformationMeasures m = ComputeInformation(histogram);
  const double hy = -(0.375 * std::log(0.375) + 0.625 * std::log(0.625));
  EXPECT_NEAR(m.entropy_x, 1.5 * std::log(2.0), 1e-14);
  EXPECT_NEAR(m.entropy_y, hy, 1e-14);
  EXPECT_NEAR(m.joint_entropy, 1.75 * std::log(2.0), 1e-14);
  EXPECT_NEAR(m.mutual_information, hy - 0.25 * std::log(2.0), 1e-14);
  EXPECT_NEAR(m.mutual_information, 0.488276443, 1e-9);
  EXPECT_NEAR(m.nid, 1.0 - (hy - 0.25 * std::log(2.0)) / (1.75 * std::log(2.0)), 1e-14);
  EXPECT_NEAR(m.nid, 0.597466284, 1e-9);
}

TEST(Metric, IndependentAndDiagonalTables) {
  // [[1, 1], [1, 1]]: independent, MI = 0, NID = 1.
  JointHistogram independent(Options(2, 2, Binning::kHard));
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) AddCount(&independent, i, j, 1);
  const InformationMeasures a = ComputeInformation(independent);
  EXPECT_NEAR(a.mutual_information, 0.0, 1e-15);
  EXPECT_NEAR(a.nid, 1.0, 1e-15);
  EXPECT_NEAR(a.joint_entropy, 2.0 * std::log(2.0), 1e-15);
  // [[2, 0], [0, 2]]: Y determines X, MI = H(X) = ln 2, NID = 0.
  JointHistogram diagonal(Options(2, 2, Binning::kHard));
  AddCount(&diagonal, 0, 0, 2);
  AddCount(&diagonal, 1, 1, 2);
  const InformationMeasures b = ComputeInformation(diagonal);
  EXPECT_NEAR(b.mutual_information, std::log(2.0), 1e-15);
  EXPECT_NEAR(b.nid, 0.0, 1e-15);
}

TEST(Metric, EmptyAndConstantHistogramsAreDefined) {
  JointHistogram histogram(Options(8, 8, Binning::kHard));
  const InformationMeasures empty = ComputeInformation(histogram);
  EXPECT_EQ(empty.samples, 0u);
  EXPECT_EQ(empty.nid, 1.0);
  EXPECT_EQ(empty.mutual_information, 0.0);
  // All samples in one bin: both constant, identical: NID 0 by definition.
  AddCount(&histogram, 3, 5, 10);
  const InformationMeasures constant = ComputeInformation(histogram);
  EXPECT_EQ(constant.samples, 10u);
  EXPECT_EQ(constant.joint_entropy, 0.0);
  EXPECT_EQ(constant.nid, 0.0);
  histogram.Reset();
  EXPECT_EQ(histogram.Samples(), 0u);
  EXPECT_EQ(histogram.TotalWeight(), 0.0);
}

TEST(Metric, HardBinsClampOutOfRangeValues) {
  // Bin b covers [b / n, (b + 1) / n); 1.0 and above go to the last bin,
  // negatives and NaN to the first.
  EXPECT_EQ(HardBin(0.0f, 32), 0);
  EXPECT_EQ(HardBin(0.031f, 32), 0);
  EXPECT_EQ(HardBin(0.032f, 32), 1);
  EXPECT_EQ(HardBin(0.999f, 32), 31);
  EXPECT_EQ(HardBin(1.0f, 32), 31);
  EXPECT_EQ(HardBin(7.0f, 32), 31);
  EXPECT_EQ(HardBin(std::numeric_limits<float>::infinity(), 32), 31);
  EXPECT_EQ(HardBin(-0.5f, 32), 0);
  EXPECT_EQ(HardBin(std::numeric_limits<float>::quiet_NaN(), 32), 0);
}

TEST(Metric, IdenticalVariablesGiveZeroNid) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> x(20000);
  for (float& v : x) v = u(rng);
  const InformationMeasures m = Measure(x, x, Options(32, 32, Binning::kHard));
  EXPECT_NEAR(m.nid, 0.0, 1e-12);
  EXPECT_NEAR(m.mutual_information, m.entropy_x, 1e-12);
  EXPECT_NEAR(m.entropy_x, m.entropy_y, 1e-12);
  EXPECT_GT(m.entropy_x, std::log(32.0) - 0.01);  // spread over all bins
}

TEST(Metric, IndependentUniformVariablesGiveNidNearOne) {
  // For independent variables the plug-in MI is biased up: 2 N MI is
  // asymptotically chi-square with (nx - 1)(ny - 1) = 961 degrees of freedom,
  // mean 961, standard deviation sqrt(2 * 961) = 43.8. So MI ~ 4.8e-4 nats and
  // NID ~ 1 - 4.8e-4 / ln 1024 = 0.99993.
  constexpr int kSamples = 1000000;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  JointHistogram histogram(Options(32, 32, Binning::kHard));
  for (int k = 0; k < kSamples; ++k) {
    const float x = u(rng);
    histogram.Add(x, u(rng));
  }
  const InformationMeasures m = ComputeInformation(histogram);
  EXPECT_GT(m.nid, 0.97);
  EXPECT_GT(m.nid, 0.999);
  const double g_statistic = 2.0 * kSamples * m.mutual_information;
  EXPECT_NEAR(g_statistic, 961.0, 5.0 * 43.8);
  EXPECT_NEAR(m.joint_entropy, std::log(1024.0), 1e-3);
}

TEST(Metric, NidIsSymmetricAndBounded) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::normal_distribution<float> noise(0.0f, 0.1f);
  for (Binning binning : {Binning::kHard, Binning::kBSpline}) {
    for (int trial = 0; trial < 20; ++trial) {
      // A partly dependent pair, with the dependence varying by trial.
      const float coupling = static_cast<float>(trial) / 19.0f;
      std::vector<float> x(3000), y(3000);
      for (std::size_t k = 0; k < x.size(); ++k) {
        x[k] = u(rng);
        y[k] = std::clamp(coupling * x[k] * x[k] + (1.0f - coupling) * u(rng) + noise(rng), 0.0f, 1.0f);
      }
      const InformationMeasures xy = Measure(x, y, Options(24, 24, binning));
      const InformationMeasures yx = Measure(y, x, Options(24, 24, binning));
      EXPECT_NEAR(xy.nid, yx.nid, 1e-12);
      EXPECT_NEAR(xy.mutual_information, yx.mutual_information, 1e-12);
      EXPECT_GE(xy.nid, 0.0);
      EXPECT_LE(xy.nid, 1.0);
      EXPECT_GE(xy.mutual_information, -1e-12);
    }
  }
}

TEST(Metric, BSplineWindowIsAPartitionOfUnity) {
  for (int bins : {2, 5, 32}) {
    for (int step = -10; step <= 10010; ++step) {
      const float v = static_cast<float>(step) / 10000.0f;  // includes values outside [0, 1]
      BSplineWindow window;
      ComputeBSplineWindow(v, bins, &window, true);
      double sum = 0.0, derivative_sum = 0.0;
      for (int k = 0; k < 4; ++k) {
        EXPECT_GE(window.weights[k], 0.0);
        sum += window.weights[k];
        derivative_sum += window.derivatives[k];
      }
      EXPECT_NEAR(sum, 1.0, 1e-14);
      EXPECT_NEAR(derivative_sum, 0.0, 1e-12);
      // The window is centred on v: its weighted bin centre is v (away from
      // the edges, where clamping moves mass).
      const double u = std::clamp(static_cast<double>(v), 0.0, 1.0) * bins - 0.5;
      double mean = 0.0;
      for (int k = 0; k < 4; ++k) mean += window.weights[k] * (window.first + k);
      EXPECT_NEAR(mean, u, 1e-12);
    }
  }
}

TEST(Metric, BSplineDerivativesMatchFiniteDifferences) {
  constexpr int kBins = 16;
  constexpr double kStep = 1e-3;
  for (int step = 1; step < 200; ++step) {
    const float v = static_cast<float>(step) / 200.0f + 0.0013f;
    BSplineWindow centre, plus, minus;
    ComputeBSplineWindow(v, kBins, &centre, true);
    ComputeBSplineWindow(static_cast<float>(v + kStep), kBins, &plus);
    ComputeBSplineWindow(static_cast<float>(v - kStep), kBins, &minus);
    if (plus.first != centre.first || minus.first != centre.first) continue;  // the window shifted
    for (int k = 0; k < 4; ++k) {
      const double numeric = (plus.weights[k] - minus.weights[k]) / (2.0 * kStep);
      EXPECT_NEAR(centre.derivatives[k], numeric, 2e-3 * kBins) << "v " << v << " k " << k;
    }
  }
}

TEST(Metric, BSplineTotalWeightEqualsSampleCount) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-0.1f, 1.1f);  // also outside, clamped
  JointHistogram histogram(Options(32, 16, Binning::kBSpline));
  constexpr int kSamples = 100000;
  for (int k = 0; k < kSamples; ++k) {
    const float x = u(rng);
    histogram.Add(x, u(rng));
  }
  EXPECT_EQ(histogram.Samples(), static_cast<std::size_t>(kSamples));
  EXPECT_NEAR(histogram.TotalWeight(), kSamples, 1e-6);
  for (double w : histogram.Weights()) EXPECT_GE(w, 0.0);
  // Edge samples stay in the table: clamped values fill the first and last bins.
  JointHistogram edges(Options(4, 4, Binning::kBSpline));
  edges.Add(0.0f, 1.0f);
  EXPECT_NEAR(edges.TotalWeight(), 1.0, 1e-15);
  EXPECT_GT(edges.Weight(0, 3), 0.5);
}

// NID of the samples with every y shifted by `shift`.
double ShiftedNid(const std::vector<float>& x, const std::vector<float>& y, float shift, Binning binning) {
  std::vector<float> shifted(y);
  for (float& v : shifted) v += shift;
  return Measure(x, shifted, Options(32, 32, binning)).nid;
}

// The kernel's lane-interleaved, margin-padded fill against AddBSpline per sample: every bin equal within
// rounding, including the edge bins that collect the clamped windows (values at and beyond 0 and 1, NaN), for
// square, oblong and tiny tables, with batches of odd sizes; Reset empties it for other bin counts.
TEST(Metric, BSplineAccumulatorGivesAddBSplinesWeights) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> inside(0.0f, 1.0f), wide(-0.2f, 1.2f);
  BSplineAccumulator accumulator;
  for (const auto& [nx, ny] : {std::pair{32, 32}, std::pair{5, 48}, std::pair{2, 3}}) {
    const HistogramOptions options = Options(nx, ny, Binning::kBSpline);
    std::vector<float> x01, y01;
    float x = 0.5f, y = 0.5f;
    for (int k = 0; k < 20000; ++k) {
      // Runs of nearby values, as in scan order, and jumps anywhere, as in random order.
      if (k % 97 == 0) x = wide(rng), y = wide(rng);
      x = std::clamp(x + 0.01f * (inside(rng) - 0.5f), -0.2f, 1.2f);
      y = std::clamp(y + 0.01f * (inside(rng) - 0.5f), -0.2f, 1.2f);
      x01.push_back(x);
      y01.push_back(y);
    }
    for (const float edge : {0.0f, 1.0f, -5.0f, 7.0f, std::numeric_limits<float>::quiet_NaN()}) {
      x01.push_back(edge);
      y01.push_back(inside(rng));
      x01.push_back(inside(rng));
      y01.push_back(edge);
    }
    JointHistogram expected(options), filled(options);
    for (std::size_t k = 0; k < x01.size(); ++k) expected.AddBSpline(x01[k], y01[k]);
    accumulator.Reset(nx, ny);
    for (std::size_t begin = 0, batch = 1; begin < x01.size(); begin += batch, batch = batch * 3 % 301 + 1) {
      const std::size_t count = std::min(batch, x01.size() - begin);
      accumulator.Add(x01.data() + begin, y01.data() + begin, count);
    }
    EXPECT_EQ(accumulator.Samples(), x01.size());
    accumulator.AddTo(&filled);
    EXPECT_EQ(filled.Samples(), expected.Samples());
    const double tolerance = 1e-12 * static_cast<double>(x01.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < expected.Weights().size(); ++i)
      worst = std::max(worst, std::abs(filled.Weights()[i] - expected.Weights()[i]));
    EXPECT_LT(worst, tolerance) << nx << " x " << ny;
    EXPECT_GT(filled.Weight(0, 0) + filled.Weight(nx - 1, ny - 1), 0.0);  // the edges were reached
    EXPECT_NEAR(filled.TotalWeight(), static_cast<double>(x01.size()), tolerance);
    EXPECT_NEAR(ComputeInformation(filled).nid, ComputeInformation(expected).nid, 1e-12);
  }
  accumulator.Reset(4, 4);  // empty again, at the new size
  JointHistogram empty(Options(4, 4, Binning::kBSpline));
  accumulator.AddTo(&empty);
  EXPECT_EQ(empty.Samples(), 0u);
  EXPECT_EQ(empty.TotalWeight(), 0.0);
}

TEST(Metric, BSplineNidIsContinuousHardNidJumps) {
  // Few samples so single bin crossings are visible. Shift every y through
  // one bin width (1/32) in steps of 1e-4 and record the largest step change.
  std::mt19937 rng(19);
  std::uniform_real_distribution<float> u(0.1f, 0.8f);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<float> x(200), y(200);
  for (std::size_t k = 0; k < x.size(); ++k) {
    x[k] = u(rng);
    y[k] = std::clamp(x[k] + noise(rng), 0.0f, 0.9f);
  }
  double largest_hard = 0.0, largest_bspline = 0.0;
  double previous_hard = ShiftedNid(x, y, 0.0f, Binning::kHard);
  double previous_bspline = ShiftedNid(x, y, 0.0f, Binning::kBSpline);
  for (int step = 1; step <= 312; ++step) {
    const float shift = 1e-4f * static_cast<float>(step);
    const double hard = ShiftedNid(x, y, shift, Binning::kHard);
    const double bspline = ShiftedNid(x, y, shift, Binning::kBSpline);
    largest_hard = std::max(largest_hard, std::abs(hard - previous_hard));
    largest_bspline = std::max(largest_bspline, std::abs(bspline - previous_bspline));
    previous_hard = hard;
    previous_bspline = bspline;
  }
  // A hard crossing moves 1 of 200 samples: a change of order 1/200 * ln(200)
  // / H ~ 1e-3 or more. The B-spline histogram moves by at most
  // 1e-4 * 32 * max|B'| (= 0.5) per sample: a Lipschitz change ~1e-4 or less.
  EXPECT_GT(largest_hard, 1e-3);
  EXPECT_LT(largest_bspline, 1e-4);
  EXPECT_LT(largest_bspline, 0.05 * largest_hard);
}

TEST(Metric, MergeEqualsOneHistogramOfAllSamples) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (Binning binning : {Binning::kHard, Binning::kBSpline}) {
    const HistogramOptions options = Options(16, 24, binning);
    JointHistogram all(options), first(options), second(options);
    for (int k = 0; k < 5000; ++k) {
      const float x = u(rng), y = u(rng);
      all.Add(x, y);
      (k % 3 == 0 ? first : second).Add(x, y);
    }
    ASSERT_TRUE(first.Merge(second));
    EXPECT_EQ(first.Samples(), all.Samples());
    for (std::size_t b = 0; b < all.Weights().size(); ++b) {
      EXPECT_NEAR(first.Weights()[b], all.Weights()[b], 1e-11);
    }
    EXPECT_NEAR(ComputeInformation(first).nid, ComputeInformation(all).nid, 1e-12);
  }
  // Histograms of different shapes do not merge.
  JointHistogram a(Options(16, 16, Binning::kHard)), b(Options(16, 8, Binning::kHard)),
      c(Options(16, 16, Binning::kBSpline));
  b.Add(0.5f, 0.5f);
  EXPECT_FALSE(a.Merge(b));
  EXPECT_FALSE(a.Merge(c));
  EXPECT_EQ(a.Samples(), 0u);
}

TEST(Metric, DependenceLowersNid) {
  // The metric ranks a better alignment lower: y = x + noise of decreasing size.
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (Binning binning : {Binning::kHard, Binning::kBSpline}) {
    double previous = 1.0;
    for (float sigma : {0.5f, 0.2f, 0.05f, 0.01f}) {
      std::normal_distribution<float> noise(0.0f, sigma);
      std::vector<float> x(20000), y(20000);
      for (std::size_t k = 0; k < x.size(); ++k) {
        x[k] = u(rng);
        y[k] = x[k] + noise(rng);
      }
      const double nid = Measure(x, y, Options(32, 32, binning)).nid;
      EXPECT_LT(nid, previous) << BinningName(binning) << " sigma " << sigma;
      previous = nid;
    }
  }
}

// y_k(theta) = y0_k + dy_k . theta: a linear model of how intensities move.
struct LinearSamples {
  std::vector<float> x, y0;
  std::vector<Vector6d> dy;
  std::vector<float> YAt(const Vector6d& theta) const {
    std::vector<float> y(y0.size());
    for (std::size_t k = 0; k < y.size(); ++k) y[k] = static_cast<float>(y0[k] + dy[k].dot(theta));
    return y;
  }
};

TEST(Metric, AnalyticGradientMatchesFiniteDifferences) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(0.05f, 0.95f);
  std::normal_distribution<double> n(0.0, 1.0);
  LinearSamples samples;
  for (int k = 0; k < 4000; ++k) {
    const float x = u(rng);
    samples.x.push_back(x);
    samples.y0.push_back(std::clamp(0.8f * x + 0.2f * u(rng), 0.1f, 0.9f));
    Vector6d d;
    for (int m = 0; m < 6; ++m) d[m] = 0.05 * n(rng);
    samples.dy.push_back(d);
  }
  const Vector6d theta = (Vector6d() << 0.1, -0.2, 0.05, 0.3, 0.0, -0.1).finished();
  const std::vector<float> y = samples.YAt(theta);
  for (MetricKind kind : {MetricKind::kNid, MetricKind::kMi}) {
    const HistogramOptions options = Options(16, 16, Binning::kBSpline);
    const CostAndGradient analytic = ComputeCostAndGradient(options, kind, samples.x, y, samples.dy);
    EXPECT_NEAR(analytic.cost, CostValue(Measure(samples.x, y, options), kind), 1e-15);
    // Central differences on a float-sampled model: a step large enough for
    // the float rounding of y (1e-7) to be negligible; the O(step^2) error
    // measured here is ~2e-6 on gradients of 1e-2 .. 1e-1.
    constexpr double kStep = 1e-3;
    for (int m = 0; m < 6; ++m) {
      Vector6d plus = theta, minus = theta;
      plus[m] += kStep;
      minus[m] -= kStep;
      const double numeric = (CostValue(Measure(samples.x, samples.YAt(plus), options), kind) -
                              CostValue(Measure(samples.x, samples.YAt(minus), options), kind)) /
                             (2.0 * kStep);
      EXPECT_NEAR(analytic.gradient[m], numeric, 2e-4 * std::abs(numeric) + 5e-6)
          << MetricKindName(kind) << " parameter " << m;
    }
    EXPECT_GT(analytic.gradient.norm(), 1e-3);  // not trivially zero
  }
  // Hard binning: piecewise constant, zero gradient.
  const CostAndGradient hard =
      ComputeCostAndGradient(Options(16, 16, Binning::kHard), MetricKind::kNid, samples.x, y, samples.dy);
  EXPECT_EQ(hard.gradient.norm(), 0.0);
}

TEST(Metric, GradientDescentStepLowersNid) {
  // Along the negative gradient the cost falls: the derivative is usable by
  // a quasi-Newton lower level. True shift 0.05 of every y, estimate from 0.
  std::mt19937 rng(37);
  std::uniform_real_distribution<float> u(0.1f, 0.8f);
  std::normal_distribution<float> noise(0.0f, 0.02f);
  std::vector<float> x(5000), y_true(5000);
  for (std::size_t k = 0; k < x.size(); ++k) {
    x[k] = u(rng);
    y_true[k] = std::clamp(x[k] * x[k] + noise(rng), 0.0f, 1.0f);
  }
  // Y depends on theta[0] as y = y_true + (theta0 - 0.05) * (x - 0.5): the
  // correct parameter is 0.05 (it aligns Y with the smooth function of X).
  std::vector<Vector6d> dy(x.size(), Vector6d::Zero());
  for (std::size_t k = 0; k < x.size(); ++k) dy[k][0] = x[k] - 0.5;
  auto y_at = [&](double theta0) {
    std::vector<float> y(x.size());
    for (std::size_t k = 0; k < x.size(); ++k) y[k] = static_cast<float>(y_true[k] + (theta0 - 0.05) * dy[k][0]);
    return y;
  };
  const HistogramOptions options = Options(32, 32, Binning::kBSpline);
  const CostAndGradient at_zero = ComputeCostAndGradient(options, MetricKind::kNid, x, y_at(0.0), dy);
  EXPECT_LT(at_zero.gradient[0], 0.0);  // increasing theta0 towards 0.05 lowers NID
  const double nid_after = CostValue(Measure(x, y_at(0.02), options), MetricKind::kNid);
  EXPECT_LT(nid_after, at_zero.cost);
}

// --- normalisation ---

TEST(Normalisation, NamesParseAndOptionsValidate) {
  EXPECT_EQ(ParseNormalisation("none"), Normalisation::kNone);
  EXPECT_EQ(ParseNormalisation("minmax"), Normalisation::kMinMax);
  EXPECT_EQ(ParseNormalisation("rank"), Normalisation::kRank);
  EXPECT_EQ(ParseNormalisation("equalise"), Normalisation::kRank);
  EXPECT_EQ(ParseNormalisation("equalize"), Normalisation::kRank);
  EXPECT_FALSE(ParseNormalisation("zscore").has_value());
  for (Normalisation n : {Normalisation::kNone, Normalisation::kMinMax, Normalisation::kRank}) {
    EXPECT_EQ(ParseNormalisation(NormalisationName(n)), n);
  }
  std::string why;
  EXPECT_TRUE(NormalisationOptions{}.IsValid(&why)) << why;
  NormalisationOptions bad;
  bad.lower_percentile = 60.0;
  bad.upper_percentile = 40.0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("percentile"), std::string::npos);
  for (const double fraction : {-0.01, 0.6, std::numeric_limits<double>::quiet_NaN()}) {
    NormalisationOptions highpass;
    highpass.intensity_highpass_width_fraction = fraction;
    EXPECT_FALSE(highpass.IsValid(&why)) << fraction;
    EXPECT_NE(why.find("high-pass"), std::string::npos) << why;
  }
}

TEST(Normalisation, HighPassKeepsTheTextureAndDropsTheRegionsBrightness) {
  // A brightness ramp across the image (a region's shading, or one material
  // brighter than another) plus a fine checkerboard texture of +-0.05.
  cv::Mat image(60, 200, CV_32FC1);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const float texture = ((r / 2 + c / 2) % 2 == 0) ? 0.05f : -0.05f;
      image.at<float>(r, c) = 0.2f + 0.6f * static_cast<float>(c) / 199.0f + texture;
    }
  }
  const cv::Mat high = HighPassImage(image, 6.0);
  ASSERT_EQ(high.type(), CV_32FC1);
  ASSERT_EQ(high.size(), image.size());
  double lowest = 0, highest = 0;
  cv::minMaxLoc(high, &lowest, &highest);
  EXPECT_NEAR(lowest, 0.0, 1e-6);  // the difference's full range maps to [0, 1]
  EXPECT_NEAR(highest, 1.0, 1e-6);
  // Away from the borders the ramp is gone: the same texture value gives the
  // same output on the dark and the bright side (the input differs by 0.48).
  const float dark = high.at<float>(30, 40), bright = high.at<float>(30, 160);
  EXPECT_NEAR(dark, bright, 0.02f);
  EXPECT_GT(high.at<float>(30, 42), high.at<float>(30, 40) + 0.2f);  // the texture stays (+ against - squares)
  EXPECT_GT(image.at<float>(30, 160) - image.at<float>(30, 40), 0.35f);
  // A constant image has no texture: 0.5 everywhere. 8-bit input is read as /255; sigma 0 is the input.
  const cv::Mat flat = HighPassImage(cv::Mat(10, 10, CV_32FC1, cv::Scalar(0.3)), 3.0);
  EXPECT_FLOAT_EQ(flat.at<float>(5, 5), 0.5f);
  cv::Mat bytes;
  image.convertTo(bytes, CV_8U, 255.0);
  cv::Mat from_bytes_expected;
  bytes.convertTo(from_bytes_expected, CV_32F, 1.0 / 255.0);
  EXPECT_LT(cv::norm(HighPassImage(bytes, 6.0), HighPassImage(from_bytes_expected, 6.0), cv::NORM_INF), 1e-6);
  EXPECT_EQ(HighPassImage(image, 0.0).data, image.data);
  EXPECT_TRUE(HighPassImage(cv::Mat(2, 2, CV_64FC1), 3.0).empty());
}

// Wide blurs through an image area-averaged down: within a fraction of a
// percent of OpenCV's own Gaussian, within the input's bounds, and OpenCV's
// own below 10 px.
TEST(Normalisation, GaussianBlurAnyWidthMatchesTheGaussian) {
  // Street-like: regions of different brightness (blurred noise at two
  // scales) and fine texture, values in [0, 1], an odd size.
  cv::Mat coarse(961, 1283, CV_32FC1), fine(961, 1283, CV_32FC1);
  cv::RNG rng(3);
  rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 1.0);
  rng.fill(fine, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(coarse, coarse, cv::Size(0, 0), 40.0);
  cv::normalize(coarse, coarse, 0.0, 0.8, cv::NORM_MINMAX);
  cv::Mat image = coarse + 0.2 * fine;
  for (const double sigma : {8.0, 12.0, 25.6, 30.0, 60.0}) {
    cv::Mat expected;
    cv::GaussianBlur(image, expected, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
    const cv::Mat blurred = GaussianBlurAnyWidth(image, sigma);
    ASSERT_EQ(blurred.size(), image.size());
    ASSERT_EQ(blurred.type(), CV_32FC1);
    double range_low = 0, range_high = 0, low = 0, high = 0;
    cv::minMaxLoc(expected, &range_low, &range_high);
    cv::minMaxLoc(blurred, &low, &high);
    const double range = range_high - range_low;
    // Away from the borders (3 sigma) and at them.
    const int margin = static_cast<int>(3 * sigma);
    const cv::Rect inner(margin, margin, image.cols - 2 * margin, image.rows - 2 * margin);
    EXPECT_LT(cv::norm(blurred(inner), expected(inner), cv::NORM_INF), 0.005 * range) << sigma;
    EXPECT_LT(cv::norm(blurred, expected, cv::NORM_INF), 0.02 * range) << sigma;
    EXPECT_GE(low, 0.0);
    EXPECT_LE(high, 1.0);
  }
  // Narrow blurs are OpenCV's, bit for bit.
  for (const double sigma : {0.5, 2.0, 7.9}) {
    cv::Mat expected;
    cv::GaussianBlur(image, expected, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
    EXPECT_EQ(cv::norm(GaussianBlurAnyWidth(image, sigma), expected, cv::NORM_INF), 0.0) << sigma;
  }
}

TEST(Normalisation, FitAndApplyIsFitThenApplyBitForBit) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uniform(-3.0f, 40.0f);
  std::uniform_int_distribution<int> level(0, 255);
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::vector<float>> sets;
  std::vector<float> mixed;
  for (int k = 0; k < 20000; ++k) mixed.push_back(k % 3 == 0 ? static_cast<float>(level(rng)) : uniform(rng));
  for (const float special : {nan, inf, -inf, 0.0f, -0.0f, nan, 255.0f}) mixed.push_back(special);
  std::shuffle(mixed.begin(), mixed.end(), rng);
  sets.push_back(mixed);
  sets.push_back({});
  sets.push_back({nan, inf, -inf});
  sets.push_back({2.0f, 2.0f, 2.0f});
  sets.push_back({-0.0f, 0.0f, 1.0f, -1.0f, nan});
  for (const auto& values : sets) {
    for (const Normalisation kind : {Normalisation::kNone, Normalisation::kMinMax, Normalisation::kRank}) {
      const ValueNormaliser normaliser = ValueNormaliser::Fit(values, kind, 2.0, 98.0);
      const std::vector<float> fast = ValueNormaliser::FitAndApply(values, kind, 2.0, 98.0);
      ASSERT_EQ(fast.size(), values.size());
      for (std::size_t k = 0; k < values.size(); ++k) {
        const float expected = normaliser(values[k]);
        ASSERT_EQ(std::memcmp(&fast[k], &expected, sizeof expected), 0)
            << NormalisationName(kind) << " value " << values[k] << ": " << fast[k] << " against " << expected;
      }
    }
  }
}

TEST(Normalisation, RankYieldsUniformValues) {
  // Skewed distinct values (exponential): after rank normalisation each of 10
  // equal bins holds n / 10 values exactly (mid-ranks (i + 0.5) / n).
  std::mt19937 rng(41);
  std::exponential_distribution<float> skewed(3.0f);
  std::vector<float> values(10000);
  for (float& v : values) v = 200.0f * skewed(rng);
  const ValueNormaliser rank = ValueNormaliser::Fit(values, Normalisation::kRank);
  std::vector<float> out(values.size());
  rank.Apply(values, out);
  std::vector<int> counts(10, 0);
  for (float v : out) {
    ASSERT_GT(v, 0.0f);
    ASSERT_LT(v, 1.0f);
    ++counts[std::min(9, static_cast<int>(v * 10.0f))];
  }
  for (int c : counts) EXPECT_NEAR(c, 1000, 1);
  // Monotone: order preserved.
  for (std::size_t k = 1; k < values.size(); ++k) {
    if (values[k] > values[k - 1]) {
      EXPECT_GE(out[k], out[k - 1]);
    }
    if (values[k] < values[k - 1]) {
      EXPECT_LE(out[k], out[k - 1]);
    }
  }
  // Values not fitted interpolate between neighbours, ends clamp.
  EXPECT_EQ(rank(-5.0f), rank(*std::min_element(values.begin(), values.end())));
  EXPECT_EQ(rank(1e9f), rank(*std::max_element(values.begin(), values.end())));
  // The rank-normalised reflectance has the maximal marginal entropy.
  JointHistogram histogram(Options(10, 2, Binning::kHard));
  for (float v : out) histogram.Add(v, 0.5f);
  EXPECT_NEAR(ComputeInformation(histogram).entropy_x, std::log(10.0), 1e-6);
}

TEST(Normalisation, RankGivesTiesTheirMidRank) {
  // Integer reflectance with ties: 0 x4, 1 x2, 5 x4  (n = 10)
  // mid-ranks: 0 -> (0 + 2) / 10 = 0.2, 1 -> (4 + 1) / 10 = 0.5, 5 -> (6 + 2) / 10 = 0.8.
  const std::vector<float> values = {5, 0, 1, 0, 5, 5, 0, 1, 0, 5};
  const ValueNormaliser rank = ValueNormaliser::Fit(values, Normalisation::kRank);
  EXPECT_FLOAT_EQ(rank(0.0f), 0.2f);
  EXPECT_FLOAT_EQ(rank(1.0f), 0.5f);
  EXPECT_FLOAT_EQ(rank(5.0f), 0.8f);
  EXPECT_FLOAT_EQ(rank(3.0f), 0.65f);  // halfway between 1 and 5
}

TEST(Normalisation, MinMaxClampsOutliers) {
  // 1000 values uniform on [0, 100] plus 5 retro-reflector outliers at 1e5.
  std::mt19937 rng(43);
  std::uniform_real_distribution<float> u(0.0f, 100.0f);
  std::vector<float> values(1000);
  for (float& v : values) v = u(rng);
  for (int k = 0; k < 5; ++k) values.push_back(1e5f);
  values.push_back(std::numeric_limits<float>::quiet_NaN());  // skipped by the fit
  const ValueNormaliser robust = ValueNormaliser::Fit(values, Normalisation::kMinMax, 1.0, 99.0);
  EXPECT_NEAR(robust.Lower(), 1.0f, 1.0f);    // 1st percentile of U(0, 100)
  EXPECT_NEAR(robust.Upper(), 99.0f, 1.5f);   // 99th percentile, the outliers are above it
  EXPECT_EQ(robust(1e5f), 1.0f);
  EXPECT_EQ(robust(-3.0f), 0.0f);
  EXPECT_NEAR(robust(50.0f), 0.5f, 0.02f);
  // Without the percentile clamp the outliers squash the data towards 0.
  const ValueNormaliser plain = ValueNormaliser::Fit(values, Normalisation::kMinMax, 0.0, 100.0);
  EXPECT_LT(plain(50.0f), 0.001f);
  // kNone clamps only; a constant input maps to 0.5.
  const ValueNormaliser none = ValueNormaliser::Fit(values, Normalisation::kNone);
  EXPECT_EQ(none(0.25f), 0.25f);
  EXPECT_EQ(none(7.0f), 1.0f);
  const std::vector<float> constant(10, 3.0f);
  EXPECT_EQ(ValueNormaliser::Fit(constant, Normalisation::kMinMax)(3.0f), 0.5f);
}

TEST(Normalisation, ImageEqualisationIsUniformAndMonotone) {
  // A dark image: intensity (col / width)^3, skewed towards 0.
  cv::Mat image(40, 256, CV_32FC1);
  for (int r = 0; r < image.rows; ++r)
    for (int c = 0; c < image.cols; ++c) image.at<float>(r, c) = std::pow(static_cast<float>(c) / 255.0f, 3.0f);
  const cv::Mat same = NormaliseImage(image, Normalisation::kNone);
  EXPECT_EQ(same.data, image.data);  // no copy
  const cv::Mat equalised = NormaliseImage(image, Normalisation::kRank);
  ASSERT_EQ(equalised.type(), CV_32FC1);
  ASSERT_EQ(equalised.size(), image.size());
  std::vector<int> counts(8, 0);
  for (int r = 0; r < equalised.rows; ++r) {
    for (int c = 0; c < equalised.cols; ++c) {
      const float v = equalised.at<float>(r, c);
      ++counts[std::min(7, static_cast<int>(v * 8.0f))];
      if (c > 0) {
        EXPECT_GT(v, equalised.at<float>(r, c - 1));
      }
    }
  }
  for (int count : counts) EXPECT_EQ(count, 40 * 256 / 8);
  // An 8-bit image is read as value / 255; other types are refused.
  cv::Mat bytes(2, 2, CV_8UC1, cv::Scalar(255));
  EXPECT_FLOAT_EQ(NormaliseImage(bytes, Normalisation::kNone).at<float>(1, 1), 1.0f);
  EXPECT_TRUE(NormaliseImage(cv::Mat(2, 2, CV_64FC1), Normalisation::kRank).empty());
  const cv::Mat stretched = NormaliseImage(image, Normalisation::kMinMax, 0.0, 100.0);
  EXPECT_FLOAT_EQ(stretched.at<float>(0, 255), 1.0f);
  EXPECT_FLOAT_EQ(stretched.at<float>(0, 0), 0.0f);
}

}  // namespace
}  // namespace scenecal
