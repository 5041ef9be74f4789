#include "core/metric.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <numeric>

#include "core/validation.hpp"

namespace scenecal {

const char* BinningName(Binning binning) { return EnumName(kBinningNames, binning); }

std::optional<Binning> ParseBinning(std::string_view name) { return ParseEnumName(kBinningNames, name); }

const char* MetricKindName(MetricKind kind) { return EnumName(kMetricKindNames, kind); }

std::optional<MetricKind> ParseMetricKind(std::string_view name) { return ParseEnumName(kMetricKindNames, name); }

bool HistogramOptions::IsValid(std::string* why) const {
  if (reflectance_bins < 2 || reflectance_bins > kMaxBins) {
    return Invalid(why, "reflectance_bins must be in [2, " + std::to_string(kMaxBins) + "], got " +
                        std::to_string(reflectance_bins));
  }
  if (intensity_bins < 2 || intensity_bins > kMaxBins) {
    return Invalid(why, "intensity_bins must be in [2, " + std::to_string(kMaxBins) + "], got " +
                        std::to_string(intensity_bins));
  }
  if (binning != Binning::kHard && binning != Binning::kBSpline) return Invalid(why, "binning is not a known value");
  return true;
}

JointHistogram::JointHistogram(const HistogramOptions& options)
    : options_(options),
      nx_(std::clamp(options.reflectance_bins, 2, HistogramOptions::kMaxBins)),
      ny_(std::clamp(options.intensity_bins, 2, HistogramOptions::kMaxBins)),
      weights_(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_), 0.0) {
  options_.reflectance_bins = nx_;
  options_.intensity_bins = ny_;
}

void JointHistogram::Reset() {
  std::fill(weights_.begin(), weights_.end(), 0.0);
  samples_ = 0;
}

bool JointHistogram::Merge(const JointHistogram& other) {
  if (other.nx_ != nx_ || other.ny_ != ny_ || other.options_.binning != options_.binning) return false;
  std::transform(weights_.begin(), weights_.end(), other.weights_.begin(), weights_.begin(), std::plus<>());
  samples_ += other.samples_;
  return true;
}

double JointHistogram::TotalWeight() const { return std::accumulate(weights_.begin(), weights_.end(), 0.0); }

namespace {

// -sum p log p over weights / total, with 0 log 0 = 0.
double Entropy(const double* weights, int count, double total) {
  double entropy = 0.0;
  for (int i = 0; i < count; ++i) {
    if (weights[i] > 0.0) {
      const double p = weights[i] / total;
      entropy -= p * std::log(p);
    }
  }
  return entropy;
}

// Marginals of a row-major nx x ny table into caller-provided arrays.
void Marginals(const JointHistogram& histogram, double* marginal_x, double* marginal_y) {
  const int nx = histogram.ReflectanceBins();
  const int ny = histogram.IntensityBins();
  const double* weights = histogram.Weights().data();
  std::fill(marginal_y, marginal_y + ny, 0.0);
  for (int i = 0; i < nx; ++i) {
    const double* row = weights + static_cast<std::size_t>(i) * ny;
    double row_sum = 0.0;
    for (int j = 0; j < ny; ++j) {
      row_sum += row[j];
      marginal_y[j] += row[j];
    }
    marginal_x[i] = row_sum;
  }
}

}  // namespace

InformationMeasures ComputeInformation(const JointHistogram& histogram) {
  InformationMeasures measures;
  measures.samples = histogram.Samples();
  const double total = histogram.TotalWeight();
  if (measures.samples == 0 || !(total > 0.0)) {
    measures.samples = 0;
    return measures;  // the documented empty result: entropies 0, nid 1
  }
  std::array<double, HistogramOptions::kMaxBins> marginal_x, marginal_y;
  Marginals(histogram, marginal_x.data(), marginal_y.data());
  const int nx = histogram.ReflectanceBins();
  const int ny = histogram.IntensityBins();
  measures.entropy_x = Entropy(marginal_x.data(), nx, total);
  measures.entropy_y = Entropy(marginal_y.data(), ny, total);
  measures.joint_entropy = Entropy(histogram.Weights().data(), nx * ny, total);
  measures.mutual_information = measures.entropy_x + measures.entropy_y - measures.joint_entropy;
  if (measures.joint_entropy > 0.0) {
    measures.nid = std::clamp((measures.joint_entropy - measures.mutual_information) / measures.joint_entropy,
                              0.0, 1.0);
  } else {
    measures.nid = 0.0;  // both constant: identical variables
  }
  return measures;
}

double CostValue(const InformationMeasures& measures, MetricKind kind) {
  return kind == MetricKind::kNid ? measures.nid : -measures.mutual_information;
}

void CostGradient::Compute(const JointHistogram& histogram, MetricKind kind) {
  nx_ = histogram.ReflectanceBins();
  ny_ = histogram.IntensityBins();
  smooth_ = histogram.GetBinning() == Binning::kBSpline;
  dcost_dweight_.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_), 0.0);
  const int padded_nx = nx_ + 2 * kPad, padded_ny = ny_ + 2 * kPad;
  padded_.assign(static_cast<std::size_t>(padded_nx) * static_cast<std::size_t>(padded_ny), 0.0);
  const InformationMeasures m = ComputeInformation(histogram);
  if (!smooth_ || m.samples == 0) return;
  const double total = histogram.TotalWeight();
  // Cost = a * (H(X) + H(Y)) + b * H(X,Y):
  //   NID = 2 - (H(X) + H(Y)) / H(X,Y)  ->  a = -1 / H(X,Y), b = (H(X) + H(Y)) / H(X,Y)^2
  //   -MI = H(X,Y) - H(X) - H(Y)        ->  a = -1,          b = 1
  double a = -1.0, b = 1.0;
  if (kind == MetricKind::kNid) {
    if (!(m.joint_entropy > 0.0)) return;  // nid pinned at 0
    a = -1.0 / m.joint_entropy;
    b = (m.entropy_x + m.entropy_y) / (m.joint_entropy * m.joint_entropy);
  }
  std::array<double, HistogramOptions::kMaxBins> marginal_x, marginal_y;
  Marginals(histogram, marginal_x.data(), marginal_y.data());
  // dH/dh = -(log p + H) / N for each entropy; empty bins (p = 0) only ever
  // meet zero weight derivatives, their limit contribution is 0.
  auto d_entropy = [total](double weight, double entropy) {
    return weight > 0.0 ? -(std::log(weight / total) + entropy) / total : 0.0;
  };
  std::array<double, HistogramOptions::kMaxBins> d_entropy_y;
  for (int j = 0; j < ny_; ++j) d_entropy_y[j] = d_entropy(marginal_y[j], m.entropy_y);
  const double* weights = histogram.Weights().data();
  for (int i = 0; i < nx_; ++i) {
    const double d_entropy_x = d_entropy(marginal_x[i], m.entropy_x);
    for (int j = 0; j < ny_; ++j) {
      const std::size_t index = static_cast<std::size_t>(i) * ny_ + j;
      if (!(weights[index] > 0.0)) continue;
      dcost_dweight_[index] = a * (d_entropy_x + d_entropy_y[j]) + b * d_entropy(weights[index], m.joint_entropy);
    }
  }
  for (int i = 0; i < padded_nx; ++i) {
    const double* row = dcost_dweight_.data() + static_cast<std::size_t>(JointHistogram::ClampBin(i - kPad, nx_)) * ny_;
    double* padded_row = padded_.data() + static_cast<std::size_t>(i) * padded_ny;
    for (int j = 0; j < padded_ny; ++j) padded_row[j] = row[JointHistogram::ClampBin(j - kPad, ny_)];
  }
}

double CostGradient::SampleDerivative(float x01, float y01) const {
  if (!smooth_ || dcost_dweight_.empty()) return 0.0;
  BSplineWindow wx, wy;
  ComputeBSplineWindow(x01, nx_, &wx);
  ComputeBSplineWindow(y01, ny_, &wy, /*with_derivatives=*/true);
  std::array<int, 4> columns;
  for (int k = 0; k < 4; ++k) columns[k] = JointHistogram::ClampBin(wy.first + k, ny_);
  // sum_b dwy_b (sum_a wx_a dcost/dh_ab), in this order (SampleDerivatives' too).
  double column[4] = {0.0, 0.0, 0.0, 0.0};
  for (int a = 0; a < 4; ++a) {
    const double* row =
        dcost_dweight_.data() + static_cast<std::size_t>(JointHistogram::ClampBin(wx.first + a, nx_)) * ny_;
    for (int b = 0; b < 4; ++b) column[b] += wx.weights[a] * row[columns[b]];
  }
  return ((column[0] * wy.derivatives[0] + column[1] * wy.derivatives[1]) + column[2] * wy.derivatives[2]) +
         column[3] * wy.derivatives[3];
}

namespace {

// ComputeBSplineWindow's arithmetic for one variable, as plain loops over a
// chunk that the compiler vectorises (std::min / std::max are ClampUnit for
// every input, NaN included: min(NaN, 1) is NaN and max(0, NaN) is 0).
constexpr int kWindowChunk = 64;

struct WindowChunk {
  alignas(64) std::int32_t first[kWindowChunk];
  alignas(64) double value[4][kWindowChunk];  // weights, or derivatives
};

// weights of x (with_derivatives = false) or derivatives of y (true).
template <bool kDerivatives>
[[gnu::always_inline]] inline void ComputeWindowChunk(const float* __restrict v01, int count, int bins, WindowChunk* __restrict out) {
  const double bins_double = bins;
  for (int k = 0; k < count; ++k) {
    const float value = v01[k];
    const double clamped = std::max(0.0, std::min(static_cast<double>(value), 1.0));
    const double u = clamped * bins_double - 0.5;
    const int base = static_cast<int>(u + 1.0) - 1;
    const double t = u - base;
    const double s = 1.0 - t;
    const double t2 = t * t;
    out->first[k] = base - 1;
    if constexpr (kDerivatives) {
      // A bit mask, not a floating-point select (which would not vectorise).
      const std::uint64_t inside = 0u - static_cast<std::uint64_t>((value > 0.0f) & (value < 1.0f));
      const double scale = std::bit_cast<double>(std::bit_cast<std::uint64_t>(bins_double) & inside);
      out->value[0][k] = -0.5 * s * s * scale;
      out->value[1][k] = (1.5 * t2 - 2.0 * t) * scale;
      out->value[2][k] = (-1.5 * t2 + t + 0.5) * scale;
      out->value[3][k] = 0.5 * t2 * scale;
    } else {
      const double t3 = t2 * t;
      constexpr double kSixth = 1.0 / 6.0;  // as ComputeBSplineWindow
      out->value[0][k] = s * s * s * kSixth;
      out->value[1][k] = (3.0 * t3 - 6.0 * t2 + 4.0) * kSixth;
      out->value[2][k] = (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * kSixth;
      out->value[3][k] = t3 * kSixth;
    }
  }
}

// Four doubles in one vector (GCC / Clang vector extension: element-wise
// arithmetic, the same roundings as scalar code).
typedef double Double4 __attribute__((vector_size(32)));

// The 4 x 4 window reads of SampleDerivativeChunk. Not vectorised across
// samples (which turns each read into 16 scalar loads), but within one: the
// four columns are summed together, so a window row is one vector load.
// (GCC: no loop vectorisation in this function; Clang: the pragma below.)
#if defined(__clang__)
#define SCENECAL_WINDOW_READ_ATTRIBUTES __attribute__((target_clones("avx2", "default")))
#else
#define SCENECAL_WINDOW_READ_ATTRIBUTES \
  __attribute__((target_clones("avx2", "default"), optimize("no-tree-loop-vectorize")))
#endif
SCENECAL_WINDOW_READ_ATTRIBUTES void ReadDerivativeWindows(const double* __restrict padded, int padded_ny, int pad,
                                                           const WindowChunk& wx, const WindowChunk& wy, int count,
                                                           double* __restrict derivatives) {
#if defined(__clang__)
#pragma clang loop vectorize(disable)
#endif
  for (int k = 0; k < count; ++k) {
    // SampleDerivative's sums in its order; the padding holds the clamped bins' values.
    const double* block = padded + static_cast<std::ptrdiff_t>(wx.first[k] + pad) * padded_ny + (wy.first[k] + pad);
    Double4 column = {0.0, 0.0, 0.0, 0.0};
    for (int a = 0; a < 4; ++a) {
      Double4 row;
      std::memcpy(&row, block + static_cast<std::ptrdiff_t>(a) * padded_ny, sizeof row);  // unaligned load
      column += wx.value[a][k] * row;
    }
    derivatives[k] = ((column[0] * wy.value[0][k] + column[1] * wy.value[1][k]) + column[2] * wy.value[2][k]) +
                     column[3] * wy.value[3][k];
  }
}

// Baseline x86-64 and AVX2 (no FMA: the same doubles as SampleDerivative).
// padded: CostGradient::padded_, padded_ny columns, pad bins on each side.
__attribute__((target_clones("avx2", "default"))) void SampleDerivativeChunk(
    const double* __restrict padded, int nx, int ny, int padded_ny, int pad, const float* __restrict x01,
    const float* __restrict y01, int count, double* __restrict derivatives) {
  WindowChunk wx, wy;
  ComputeWindowChunk<false>(x01, count, nx, &wx);
  ComputeWindowChunk<true>(y01, count, ny, &wy);
  ReadDerivativeWindows(padded, padded_ny, pad, wx, wy, count, derivatives);
}

// BSplineAccumulator::Add over one chunk: sample k's window goes into lane
// k % kLanes, at (first + kPad) in both variables (no clamping). Baseline
// x86-64 and AVX2, no FMA: the same weights on every machine.
__attribute__((target_clones("avx2", "default"))) void AccumulateBSplineChunk(
    double* __restrict lanes, std::size_t lane_size, int row_stride, int nx, int ny,
    const float* __restrict x01, const float* __restrict y01, int count) {
  WindowChunk wx, wy;
  ComputeWindowChunk<false>(x01, count, nx, &wx);
  ComputeWindowChunk<false>(y01, count, ny, &wy);
  for (int k = 0; k < count; ++k) {
    constexpr int kLanes = BSplineAccumulator::kLanes, kPad = BSplineAccumulator::kPad;
    double* cell = lanes + static_cast<std::size_t>(k % kLanes) * lane_size +
                   static_cast<std::ptrdiff_t>(wx.first[k] + kPad) * row_stride + (wy.first[k] + kPad);
    const double wy0 = wy.value[0][k], wy1 = wy.value[1][k], wy2 = wy.value[2][k], wy3 = wy.value[3][k];
    for (int a = 0; a < 4; ++a) {
      double* row = cell + static_cast<std::ptrdiff_t>(a) * row_stride;
      const double weight_x = wx.value[a][k];
      row[0] += weight_x * wy0;
      row[1] += weight_x * wy1;
      row[2] += weight_x * wy2;
      row[3] += weight_x * wy3;
    }
  }
}

}  // namespace

void BSplineAccumulator::Reset(int reflectance_bins, int intensity_bins) {
  nx_ = std::clamp(reflectance_bins, 2, HistogramOptions::kMaxBins);
  ny_ = std::clamp(intensity_bins, 2, HistogramOptions::kMaxBins);
  row_stride_ = ny_ + 2 * kPad;
  lane_size_ = static_cast<std::size_t>(nx_ + 2 * kPad) * static_cast<std::size_t>(row_stride_);
  lanes_.assign(lane_size_ * kLanes, 0.0);
  samples_ = 0;
}

void BSplineAccumulator::Add(const float* x01, const float* y01, std::size_t count) {
  if (lanes_.empty()) return;
  // Chunks of a multiple of kLanes samples: sample k's lane is its index in the whole batch modulo kLanes.
  static_assert(kWindowChunk % kLanes == 0);
  for (std::size_t begin = 0; begin < count; begin += kWindowChunk) {
    const int chunk = static_cast<int>(std::min<std::size_t>(kWindowChunk, count - begin));
    AccumulateBSplineChunk(lanes_.data(), lane_size_, row_stride_, nx_, ny_, x01 + begin, y01 + begin, chunk);
  }
  samples_ += count;
}

void BSplineAccumulator::AddTo(JointHistogram* histogram) const {
  if (lanes_.empty() || histogram->ReflectanceBins() != nx_ || histogram->IntensityBins() != ny_) return;
  thread_local std::vector<double> folded;
  folded.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_), 0.0);
  const int padded_rows = nx_ + 2 * kPad;
  for (int lane = 0; lane < kLanes; ++lane) {
    const double* table = lanes_.data() + static_cast<std::size_t>(lane) * lane_size_;
    for (int i = 0; i < padded_rows; ++i) {
      double* row = folded.data() + static_cast<std::size_t>(JointHistogram::ClampBin(i - kPad, nx_)) * ny_;
      const double* padded_row = table + static_cast<std::size_t>(i) * row_stride_;
      for (int j = 0; j < kPad; ++j) row[0] += padded_row[j];
      for (int j = 0; j < ny_; ++j) row[j] += padded_row[j + kPad];
      for (int j = ny_ + kPad; j < row_stride_; ++j) row[ny_ - 1] += padded_row[j];
    }
  }
  histogram->AddWeights(folded.data(), samples_);
}

void CostGradient::SampleDerivatives(const float* x01, const float* y01, std::size_t count,
                                     double* derivatives) const {
  if (!smooth_ || padded_.empty()) {
    std::fill(derivatives, derivatives + count, 0.0);
    return;
  }
  for (std::size_t begin = 0; begin < count; begin += kWindowChunk) {
    const int chunk = static_cast<int>(std::min<std::size_t>(kWindowChunk, count - begin));
    SampleDerivativeChunk(padded_.data(), nx_, ny_, ny_ + 2 * kPad, kPad, x01 + begin, y01 + begin, chunk,
                          derivatives + begin);
  }
}

CostAndGradient ComputeCostAndGradient(const HistogramOptions& options, MetricKind kind,
                                       std::span<const float> x01, std::span<const float> y01,
                                       std::span<const Vector6d> dy01_dtheta) {
  CostAndGradient result;
  const std::size_t count = std::min({x01.size(), y01.size(), dy01_dtheta.size()});
  JointHistogram histogram(options);
  for (std::size_t k = 0; k < count; ++k) histogram.Add(x01[k], y01[k]);
  result.measures = ComputeInformation(histogram);
  result.cost = CostValue(result.measures, kind);
  CostGradient gradient;
  gradient.Compute(histogram, kind);
  for (std::size_t k = 0; k < count; ++k) {
    result.gradient += gradient.SampleDerivative(x01[k], y01[k]) * dy01_dtheta[k];
  }
  return result;
}

}  // namespace scenecal
