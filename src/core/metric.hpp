// Joint histograms of lidar reflectance and image intensity, and the
// information measures computed from them (paper section III-A, eqs. 5-8):
//   H(X)   = -sum_x p(x) log p(x)                  (natural log, nats)
//   MI     = H(X) + H(Y) - H(X,Y)
//   NID    = (H(X,Y) - MI) / H(X,Y)                in [0, 1]
// X is the reflectance of a lidar point, Y the intensity of the pixel it
// projects to; both are mapped to [0, 1] beforehand (core/normalisation.hpp).
//
// Hot path: JointHistogram::Add is inline, allocation-free and branch-light.
// For threads, fill one histogram per thread and Merge them.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/enum_names.hpp"
#include "core/geometry.hpp"

namespace scenecal {

// How a sample is assigned to bins.
//  kHard:    one bin per variable (the paper). The cost is piecewise constant
//            in the pixel intensity.
//  kBSpline: cubic B-spline Parzen window: a sample spreads over 4 x 4
//            neighbouring bins with the cubic B-spline weights of its
//            distance to the bin centres, so the histogram, and the cost, are
//            C2 functions of y (and x). At the edges the bin indices are
//            clamped into the table, so every sample contributes weight 1.
enum class Binning { kHard, kBSpline };
inline constexpr auto kBinningNames =
    MakeEnumNames<Binning>({{Binning::kHard, "hard"}, {Binning::kBSpline, "bspline"}});

// Which information measure the optimiser uses.
enum class MetricKind { kNid, kMi };
inline constexpr auto kMetricKindNames =
    MakeEnumNames<MetricKind>({{MetricKind::kNid, "nid"}, {MetricKind::kMi, "mi"}});

const char* BinningName(Binning binning);                    // "hard", "bspline"
std::optional<Binning> ParseBinning(std::string_view name);  // inverse; nullopt if unknown
const char* MetricKindName(MetricKind kind);                 // "nid", "mi"
std::optional<MetricKind> ParseMetricKind(std::string_view name);

struct HistogramOptions {
  static constexpr int kMaxBins = 512;  // per variable; bounds the stack scratch of ComputeInformation
  int reflectance_bins = 32;            // bins of X, in [2, kMaxBins]
  int intensity_bins = 32;              // bins of Y, in [2, kMaxBins]
  Binning binning = Binning::kHard;

  bool IsValid(std::string* why) const;
};

// Cubic B-spline Parzen window of one variable. Bin b covers
// [b / bins, (b + 1) / bins) and has its centre at (b + 0.5) / bins. A value
// v01 in [0, 1] (clamped; NaN counts as 0) touches bins first .. first + 3
// (before clamping into [0, bins - 1]) with weights[k] >= 0, sum 1.
struct BSplineWindow {
  int first = 0;
  std::array<double, 4> weights{};
  std::array<double, 4> derivatives{};  // d weights[k] / d v01 (0 where v01 is clamped)
};

// Clamps v01 to [0, 1]; NaN maps to 0.
inline double ClampUnit(double v01) { return v01 > 0.0 ? (v01 < 1.0 ? v01 : 1.0) : 0.0; }

// The bin of v01 under hard binning: floor(v01 * bins), clamped into the table.
inline int HardBin(float v01, int bins) {
  const double scaled = ClampUnit(v01) * bins;
  const int bin = static_cast<int>(scaled);
  return bin < bins ? bin : bins - 1;
}

// Fills the B-spline window of v01; derivatives only when with_derivatives.
inline void ComputeBSplineWindow(float v01, int bins, BSplineWindow* window, bool with_derivatives = false) {
  const bool inside = v01 > 0.0f && v01 < 1.0f;
  const double u = ClampUnit(v01) * bins - 0.5;  // position in units of bins, relative to bin centres
  // u >= -0.5, so truncating u + 1 is floor(u) + 1 (no libm floor call on baseline x86-64).
  const int base = static_cast<int>(u + 1.0) - 1;
  const double t = u - base;  // in [0, 1)
  const double s = 1.0 - t;
  const double t2 = t * t, t3 = t2 * t;
  window->first = base - 1;
  // Times 1/6, not divided by 6: a division per weight was a tenth of the B-spline kernel's time.
  constexpr double kSixth = 1.0 / 6.0;
  window->weights = {s * s * s * kSixth, (3.0 * t3 - 6.0 * t2 + 4.0) * kSixth,
                     (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * kSixth, t3 * kSixth};
  if (with_derivatives) {
    const double scale = inside ? static_cast<double>(bins) : 0.0;  // du/dv01
    window->derivatives = {-0.5 * s * s * scale, (1.5 * t2 - 2.0 * t) * scale,
                           (-1.5 * t2 + t + 0.5) * scale, 0.5 * t2 * scale};
  }
}

// Weighted counts over reflectance_bins x intensity_bins bins, stored
// row-major: Weight(x_bin, y_bin) = Weights()[x_bin * intensity_bins + y_bin].
class JointHistogram {
 public:
  // options must be valid (HistogramOptions::IsValid); invalid sizes are
  // clamped into [2, kMaxBins] so the object is always usable.
  explicit JointHistogram(const HistogramOptions& options = {});

  void Reset();

  // Adds one sample (x01 = normalised reflectance, y01 = normalised
  // intensity, both in [0, 1]; values outside are clamped).
  void Add(float x01, float y01) {
    if (options_.binning == Binning::kHard) {
      AddHard(x01, y01);
    } else {
      AddBSpline(x01, y01);
    }
  }
  void AddHard(float x01, float y01) {
    weights_[static_cast<std::size_t>(HardBin(x01, nx_) * ny_ + HardBin(y01, ny_))] += 1.0;
    ++samples_;
  }
  void AddBSpline(float x01, float y01) {
    BSplineWindow wx, wy;
    ComputeBSplineWindow(x01, nx_, &wx);
    ComputeBSplineWindow(y01, ny_, &wy);
    ++samples_;
    if (wy.first >= 0 && wy.first + 3 < ny_) {
      // Interior in y: four contiguous columns (the common case, vectorisable).
      for (int a = 0; a < 4; ++a) {
        double* cell = weights_.data() + static_cast<std::size_t>(ClampBin(wx.first + a, nx_)) * ny_ + wy.first;
        const double weight_x = wx.weights[a];
        for (int b = 0; b < 4; ++b) cell[b] += weight_x * wy.weights[b];
      }
      return;
    }
    std::array<int, 4> columns;
    for (int k = 0; k < 4; ++k) columns[k] = ClampBin(wy.first + k, ny_);
    for (int a = 0; a < 4; ++a) {
      double* row = weights_.data() + static_cast<std::size_t>(ClampBin(wx.first + a, nx_)) * ny_;
      const double weight_x = wx.weights[a];
      for (int b = 0; b < 4; ++b) row[columns[b]] += weight_x * wy.weights[b];
    }
  }

  // Adds integer bin counts (row-major like Weights(), nx * ny entries) that
  // stand for `samples` hard-binned samples: the fast path of cost kernels,
  // which count into a per-thread integer table and add it once. Exact.
  void AddCounts(const std::uint32_t* counts, std::size_t samples) {
    for (std::size_t i = 0; i < weights_.size(); ++i) weights_[i] += static_cast<double>(counts[i]);
    samples_ += samples;
  }

  // Adds a table of weights (row-major like Weights(), nx * ny entries) that
  // stands for `samples` samples (BSplineAccumulator::AddTo).
  void AddWeights(const double* weights, std::size_t samples) {
    for (std::size_t i = 0; i < weights_.size(); ++i) weights_[i] += weights[i];
    samples_ += samples;
  }

  // Adds the other histogram's weights and samples. Returns false (and
  // changes nothing) when the bin counts or binning differ.
  bool Merge(const JointHistogram& other);

  double TotalWeight() const;                      // sum of all bin weights (= Samples() up to rounding)
  std::size_t Samples() const { return samples_; }  // number of Add calls (merged in)
  int ReflectanceBins() const { return nx_; }
  int IntensityBins() const { return ny_; }
  Binning GetBinning() const { return options_.binning; }
  const HistogramOptions& Options() const { return options_; }
  double Weight(int x_bin, int y_bin) const { return weights_[static_cast<std::size_t>(x_bin * ny_ + y_bin)]; }
  const std::vector<double>& Weights() const { return weights_; }

  static int ClampBin(int bin, int bins) { return bin < 0 ? 0 : (bin < bins ? bin : bins - 1); }

 private:
  HistogramOptions options_;
  int nx_ = 0;  // reflectance bins
  int ny_ = 0;  // intensity bins
  std::vector<double> weights_;
  std::size_t samples_ = 0;
};

// The B-spline cost kernel's histogram fill: the weights of AddBSpline per
// sample, equal within rounding (not bit for bit: the sums run in another
// order). Samples go round-robin into kLanes tables, so that consecutive
// samples, which in scan order fall into the same bins, do not wait for each
// other's stores; each table has kPad bins of margin on every side, so a
// sample's 4 x 4 window is added without clamping or branches; AddTo folds the
// margins onto the edge bins (the clamping of AddBSpline) and the lanes
// together. Deterministic: the same samples in the same order give the same
// weights. Storage is kept across Reset (one per thread, reused).
class BSplineAccumulator {
 public:
  // Empties the tables for nx x ny bins (each in [2, HistogramOptions::kMaxBins]).
  void Reset(int reflectance_bins, int intensity_bins);
  // AddBSpline(x01[k], y01[k]) for k = 0 .. count - 1 (within rounding).
  void Add(const float* x01, const float* y01, std::size_t count);
  // Adds the weights and the sample count to histogram (whose bins must be Reset's).
  void AddTo(JointHistogram* histogram) const;
  std::size_t Samples() const { return samples_; }

  static constexpr int kLanes = 4;
  static constexpr int kPad = 2;  // window bins run from -2 to bins + 1

 private:
  int nx_ = 0, ny_ = 0;
  int row_stride_ = 0;          // ny + 2 kPad, in doubles
  std::size_t lane_size_ = 0;   // (nx + 2 kPad) * row_stride_
  std::vector<double> lanes_;   // kLanes tables, each lane_size_ doubles
  std::size_t samples_ = 0;
};

// Entropies in nats. For an empty histogram (samples == 0) every entropy and
// MI are 0 and nid is 1 (no evidence of any relation). When the joint entropy
// is 0 (all weight in one bin: both variables constant) the variables are
// taken as identical and nid is 0; callers should require a minimum number of
// samples before trusting any value. nid is clamped to [0, 1] against rounding.
struct InformationMeasures {
  double entropy_x = 0.0;      // H(X), reflectance
  double entropy_y = 0.0;      // H(Y), intensity
  double joint_entropy = 0.0;  // H(X,Y)
  double mutual_information = 0.0;
  double nid = 1.0;
  std::size_t samples = 0;
};

InformationMeasures ComputeInformation(const JointHistogram& histogram);

// The value to MINIMISE: NID for kNid, -MI for kMi. This is the `cost` the
// calibration result reports for a pair (averaged over its scenes).
double CostValue(const InformationMeasures& measures, MetricKind kind);

// Analytic gradient of the cost for B-spline binning.
//
// The cost is a function of the bin weights h_ij. With the set of samples
// held fixed (a sample entering or leaving the image is not differentiable
// and is ignored), each sample's X is constant and only its Y moves, so
//   dCost/dtheta = sum_k dCost/dy_k * dy_k/dtheta,
//   dCost/dy_k   = sum_ij dCost/dh_ij * wx_i(x_k) * dwy_j/dy(y_k).
// Use: fill the histogram with all samples, Compute() the bin derivatives once,
// then ask SampleDerivative for each sample (thread-safe, const). For hard
// binning the cost is piecewise constant and every derivative is 0.
class CostGradient {
 public:
  // dCost/dh_ij at the histogram's weights (total weight N free:
  // dH/dh_ij = -(log p_ij + H) / N). Reuses storage across calls.
  void Compute(const JointHistogram& histogram, MetricKind kind);

  // dCost/dy01 of one sample (x01, y01), normalised values as added.
  double SampleDerivative(float x01, float y01) const;
  // SampleDerivative of count samples: derivatives[k] = SampleDerivative(x01[k], y01[k])
  // (the same arithmetic, bit-identical), with the B-spline windows computed in
  // vectorised loops over chunks of samples and each sample's 4 x 4 bins read
  // from a padded table (no clamping): the gradient kernel's batch form.
  void SampleDerivatives(const float* x01, const float* y01, std::size_t count, double* derivatives) const;

  // Row-major like JointHistogram::Weights(); empty bins get 0 (the limit).
  const std::vector<double>& BinDerivatives() const { return dcost_dweight_; }

 private:
  int nx_ = 0, ny_ = 0;
  bool smooth_ = false;  // B-spline binning
  std::vector<double> dcost_dweight_;
  // dcost_dweight_ with kPad edge copies on every side ((nx + 2 kPad) x (ny + 2 kPad),
  // row-major): padded(i + kPad, j + kPad) = dcost_dweight(ClampBin(i), ClampBin(j)) for
  // the window bins -2 .. bins + 1, so SampleDerivatives reads 4 x 4 blocks without clamping.
  static constexpr int kPad = 2;
  std::vector<double> padded_;
};

// Convenience: builds the histogram of the samples, and returns the cost and
// dCost/dtheta = sum_k dCost/dy_k * dy01_dtheta[k] (theta any 6-parameter
// update, e.g. a twist of T_camera_lidar). The spans must have equal sizes.
struct CostAndGradient {
  InformationMeasures measures;
  double cost = 0.0;
  Vector6d gradient = Vector6d::Zero();
};
CostAndGradient ComputeCostAndGradient(const HistogramOptions& options, MetricKind kind,
                                       std::span<const float> x01, std::span<const float> y01,
                                       std::span<const Vector6d> dy01_dtheta);

}  // namespace scenecal
