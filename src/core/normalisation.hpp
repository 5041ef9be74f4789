// Static mapping of lidar reflectance and image intensity to [0, 1] before
// binning (core/metric.hpp). Done once per scene, not per cost evaluation:
// fit a ValueNormaliser on the scene's reflectances (all points of its
// swathe), then map each point; normalise each image once.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/enum_names.hpp"

namespace scenecal {

// kNone:   values are taken as already in [0, 1] and only clamped.
// kMinMax: robust linear stretch: the lower..upper percentile (default the
//          1st..99th) maps to 0..1, values beyond are clamped (outliers such
//          as retro-reflectors do not squash the rest).
// kRank:   empirical CDF (histogram equalisation): a value maps to its
//          mid-rank (count below + half the count equal) / count, so the
//          fitted values become uniform on [0, 1]. Values not in the fitted
//          set are interpolated linearly between neighbouring distinct values.
enum class Normalisation { kNone, kMinMax, kRank };
// "equalise" and "equalize" are accepted aliases of "rank".
inline constexpr auto kNormalisationNames = MakeEnumNames<Normalisation>(
    {{Normalisation::kNone, "none"}, {Normalisation::kMinMax, "minmax"}, {Normalisation::kRank, "rank"},
     {Normalisation::kRank, "equalise"}, {Normalisation::kRank, "equalize"}});

const char* NormalisationName(Normalisation normalisation);  // "none", "minmax", "rank"
// Accepts "none", "minmax", "rank", and "equalise"/"equalize" for kRank.
std::optional<Normalisation> ParseNormalisation(std::string_view name);

struct NormalisationOptions {
  Normalisation reflectance = Normalisation::kRank;  // lidar reflectance (any non-negative scale)
  Normalisation intensity = Normalisation::kNone;    // image intensity (already [0, 1])
  double lower_percentile = 1.0;                     // percent, kMinMax only
  double upper_percentile = 99.0;                    // percent, kMinMax only
  // When > 0, the sharp image of the final stages (no blur) loses its local
  // mean (HighPassImage, Gaussian sigma = this fraction of the image width;
  // 0 = off): what is left is the texture and the edges, not the brightness of
  // whole regions, which relates to the lidar's infrared reflectance
  // differently material by material (on simulated drives that moved the
  // recommended push-broom setting's minimum 0.13-0.31 deg off the truth;
  // docs/findings.md, "Why the push-broom setting scores near and far returns apart, and the images' texture"). The blurred coarse stages keep the whole
  // image: its large regions give the wide basin.
  double intensity_highpass_width_fraction = 0.0;

  bool IsValid(std::string* why) const;
};

// A monotone (non-decreasing) map of one variable to [0, 1], fitted once.
class ValueNormaliser {
 public:
  // The identity clamped to [0, 1] (kNone).
  ValueNormaliser() = default;

  // Fits to the finite entries of values (non-finite ones are skipped).
  // Percentiles are in percent, used by kMinMax only, interpolated between
  // order statistics. With no finite value, the result maps everything to 0.5.
  static ValueNormaliser Fit(std::span<const float> values, Normalisation normalisation,
                             double lower_percentile = 1.0, double upper_percentile = 99.0);

  // The normalised value in [0, 1]; NaN maps to 0.
  float operator()(float value) const;

  // Maps values into out (sizes must match; extra entries are left alone).
  void Apply(std::span<const float> values, std::span<float> out) const;

  // Fit(values, ...) applied to the same values, equal bit for bit. kRank in
  // one sort of (value, index) keys instead of a sort and a binary search per
  // value: a swathe's 0.1-0.2 M reflectances took ~10 % of a push-broom
  // calibration's processor time the other way.
  static std::vector<float> FitAndApply(std::span<const float> values, Normalisation normalisation,
                                        double lower_percentile = 1.0, double upper_percentile = 99.0);

  Normalisation Kind() const { return kind_; }
  // kMinMax: the values mapped to 0 and 1.
  float Lower() const { return lower_; }
  float Upper() const { return upper_; }

 private:
  Normalisation kind_ = Normalisation::kNone;
  bool empty_ = false;  // fitted on no finite value
  float lower_ = 0.0f, upper_ = 1.0f;
  std::vector<float> distinct_;  // kRank: sorted distinct fitted values
  std::vector<float> cdf_;       // kRank: mid-rank CDF at each distinct value
};

// Returns the image (CV_32FC1, intensities in [0, 1], the GreyImage
// invariant) normalised with `normalisation` over all its pixels, as CV_32FC1.
// kNone returns a CV_32FC1 input itself (no copy). A CV_8UC1 input is read as
// value / 255. Any other type (or an empty image) returns an empty Mat.
cv::Mat NormaliseImage(const cv::Mat& intensity, Normalisation normalisation, double lower_percentile = 1.0,
                       double upper_percentile = 99.0);

// A Gaussian blur of sigma_px pixels (mirrored at the border) that costs the
// same at any width: the image is area-averaged down by a factor f = sigma / 5
// (rounded down; below 2, i.e. sigma < 10 px, it is cv::GaussianBlur itself),
// blurred there so that the whole chain (box, Gaussian, bilinear
// interpolation back up) has the variance sigma^2, and interpolated back to
// its size. Each step is a convex combination, so the result stays within the
// input's bounds. On a 1280x960 float image at sigma 25.6 px (the push-broom
// setting's first stage) cv::GaussianBlur took 85 ms on one core; this takes a
// few ms and differs from it by under 0.5 % of the image's range
// (0.1 % at 25.6 px, Normalisation.GaussianBlurAnyWidthMatchesTheGaussian).
cv::Mat GaussianBlurAnyWidth(const cv::Mat& image, double sigma_px);

// The image (CV_32FC1 in [0, 1], or CV_8UC1 read as value / 255) less its
// Gaussian-smoothed self (GaussianBlurAnyWidth, sigma_px pixels), mapped
// linearly from the difference's full range to [0, 1] (0.5 where the image is
// constant), as CV_32FC1. sigma_px <= 0 returns the input as NormaliseImage
// with kNone would; any other type (or an empty image) returns an empty Mat.
cv::Mat HighPassImage(const cv::Mat& intensity, double sigma_px);

}  // namespace scenecal
