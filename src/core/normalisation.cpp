#include "core/normalisation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/validation.hpp"

namespace scenecal {

const char* NormalisationName(Normalisation normalisation) { return EnumName(kNormalisationNames, normalisation); }

std::optional<Normalisation> ParseNormalisation(std::string_view name) {
  return ParseEnumName(kNormalisationNames, name);
}

bool NormalisationOptions::IsValid(std::string* why) const {
  if (!(intensity_highpass_width_fraction >= 0.0 && intensity_highpass_width_fraction <= 0.5)) {
    return Invalid(why, "intensity high-pass sigma must be a fraction of the image width in [0, 0.5], got " +
                        std::to_string(intensity_highpass_width_fraction));
  }
  if (!(lower_percentile >= 0.0 && lower_percentile < upper_percentile && upper_percentile <= 100.0)) {
    return Invalid(why, "percentiles must satisfy 0 <= lower < upper <= 100, got lower " +
                            std::to_string(lower_percentile) + ", upper " + std::to_string(upper_percentile));
  }
  return true;
}

namespace {

// Percentile (percent) of sorted values, interpolated between order statistics.
float Percentile(const std::vector<float>& sorted, double percent) {
  const double position = std::clamp(percent, 0.0, 100.0) / 100.0 * static_cast<double>(sorted.size() - 1);
  const auto below = static_cast<std::size_t>(std::floor(position));
  const std::size_t above = std::min(below + 1, sorted.size() - 1);
  const double fraction = position - static_cast<double>(below);
  return static_cast<float>(sorted[below] + fraction * (static_cast<double>(sorted[above]) - sorted[below]));
}

}  // namespace

ValueNormaliser ValueNormaliser::Fit(std::span<const float> values, Normalisation normalisation,
                                     double lower_percentile, double upper_percentile) {
  ValueNormaliser normaliser;
  normaliser.kind_ = normalisation;
  if (normalisation == Normalisation::kNone) return normaliser;
  std::vector<float> sorted;
  sorted.reserve(values.size());
  for (float v : values) {
    if (std::isfinite(v)) sorted.push_back(v);
  }
  if (sorted.empty()) {
    normaliser.empty_ = true;
    return normaliser;
  }
  std::sort(sorted.begin(), sorted.end());
  if (normalisation == Normalisation::kMinMax) {
    normaliser.lower_ = Percentile(sorted, lower_percentile);
    normaliser.upper_ = Percentile(sorted, upper_percentile);
    return normaliser;
  }
  // kRank: mid-rank CDF of each distinct value, so ties share one value and
  // distinct values (i + 0.5) / n are exactly uniform.
  const double count = static_cast<double>(sorted.size());
  for (std::size_t begin = 0; begin < sorted.size();) {
    const std::size_t end =
        static_cast<std::size_t>(std::upper_bound(sorted.begin() + static_cast<std::ptrdiff_t>(begin), sorted.end(),
                                                  sorted[begin]) -
                                 sorted.begin());
    normaliser.distinct_.push_back(sorted[begin]);
    normaliser.cdf_.push_back(static_cast<float>((static_cast<double>(begin) + 0.5 * static_cast<double>(end - begin)) / count));
    begin = end;
  }
  normaliser.lower_ = normaliser.distinct_.front();
  normaliser.upper_ = normaliser.distinct_.back();
  return normaliser;
}

float ValueNormaliser::operator()(float value) const {
  if (std::isnan(value)) return 0.0f;
  if (empty_) return 0.5f;
  switch (kind_) {
    case Normalisation::kNone:
      return std::clamp(value, 0.0f, 1.0f);
    case Normalisation::kMinMax:
      if (!(upper_ > lower_)) return value < lower_ ? 0.0f : (value > upper_ ? 1.0f : 0.5f);
      return std::clamp((value - lower_) / (upper_ - lower_), 0.0f, 1.0f);
    case Normalisation::kRank: {
      // First distinct value > value; the CDF is piecewise linear between
      // distinct values and constant beyond the ends.
      const auto above = std::upper_bound(distinct_.begin(), distinct_.end(), value);
      if (above == distinct_.begin()) return cdf_.front();
      const std::size_t i = static_cast<std::size_t>(above - distinct_.begin()) - 1;
      if (above == distinct_.end() || distinct_[i] == value) return cdf_[i];
      const float fraction = (value - distinct_[i]) / (distinct_[i + 1] - distinct_[i]);
      return cdf_[i] + fraction * (cdf_[i + 1] - cdf_[i]);
    }
  }
  return 0.0f;
}

void ValueNormaliser::Apply(std::span<const float> values, std::span<float> out) const {
  const std::size_t count = std::min(values.size(), out.size());
  for (std::size_t k = 0; k < count; ++k) out[k] = (*this)(values[k]);
}

namespace {

// A key whose unsigned order is the float's order (finite values), with the
// value's index in the low 32 bits.
std::uint64_t OrderedKey(float value, std::uint32_t index) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  bits = (bits & 0x80000000u) != 0 ? ~bits : (bits | 0x80000000u);
  return (static_cast<std::uint64_t>(bits) << 32) | index;
}

}  // namespace

std::vector<float> ValueNormaliser::FitAndApply(std::span<const float> values, Normalisation normalisation,
                                                double lower_percentile, double upper_percentile) {
  std::vector<float> out(values.size());
  if (normalisation != Normalisation::kRank || values.size() >= (std::size_t{1} << 32)) {
    Fit(values, normalisation, lower_percentile, upper_percentile).Apply(values, out);
    return out;
  }
  std::vector<std::uint64_t> keys;
  keys.reserve(values.size());
  for (std::size_t k = 0; k < values.size(); ++k) {
    // -0 and +0 are one value (as in Fit's sort and upper_bound).
    if (std::isfinite(values[k]))
      keys.push_back(OrderedKey(values[k] == 0.0f ? 0.0f : values[k], static_cast<std::uint32_t>(k)));
  }
  if (keys.empty()) {  // no finite value: Fit's empty normaliser
    Fit(values, normalisation).Apply(values, out);
    return out;
  }
  std::sort(keys.begin(), keys.end());
  // Fit's mid-rank CDF, the same expression: runs of equal values share it.
  const double count = static_cast<double>(keys.size());
  float lowest_cdf = 0.0f, highest_cdf = 0.0f;
  for (std::size_t begin = 0; begin < keys.size();) {
    std::size_t end = begin + 1;
    while (end < keys.size() && (keys[end] >> 32) == (keys[begin] >> 32)) ++end;
    const float cdf =
        static_cast<float>((static_cast<double>(begin) + 0.5 * static_cast<double>(end - begin)) / count);
    for (std::size_t i = begin; i < end; ++i) out[keys[i] & 0xffffffffu] = cdf;
    if (begin == 0) lowest_cdf = cdf;
    highest_cdf = cdf;
    begin = end;
  }
  // Non-finite values as operator() maps them: NaN to 0, -inf below the
  // lowest distinct value, +inf beyond the highest.
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (std::isnan(values[k])) out[k] = 0.0f;
    else if (std::isinf(values[k])) out[k] = values[k] < 0.0f ? lowest_cdf : highest_cdf;
  }
  return out;
}

cv::Mat NormaliseImage(const cv::Mat& intensity, Normalisation normalisation, double lower_percentile,
                       double upper_percentile) {
  if (intensity.empty()) return {};
  cv::Mat grey;
  if (intensity.type() == CV_32FC1) {
    grey = intensity;
  } else if (intensity.type() == CV_8UC1) {
    intensity.convertTo(grey, CV_32F, 1.0 / 255.0);
  } else {
    return {};
  }
  if (normalisation == Normalisation::kNone) return grey;
  const cv::Mat continuous = grey.isContinuous() ? grey : grey.clone();
  const std::span<const float> pixels(continuous.ptr<float>(), continuous.total());
  const ValueNormaliser normaliser =
      ValueNormaliser::Fit(pixels, normalisation, lower_percentile, upper_percentile);
  cv::Mat out(grey.size(), CV_32FC1);
  normaliser.Apply(pixels, std::span<float>(out.ptr<float>(), out.total()));
  return out;
}

cv::Mat GaussianBlurAnyWidth(const cv::Mat& image, double sigma_px) {
  cv::Mat out;
  const int factor = static_cast<int>(std::floor(sigma_px / 5.0));
  if (factor < 2 || image.cols < 4 * factor || image.rows < 4 * factor) {
    cv::GaussianBlur(image, out, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REFLECT);
    return out;
  }
  const double f = factor;
  const cv::Size small_size(static_cast<int>(std::ceil(image.cols / f)), static_cast<int>(std::ceil(image.rows / f)));
  cv::Mat small;
  cv::resize(image, small, small_size, 0.0, 0.0, cv::INTER_AREA);
  // Variances in full-size pixels^2: the area average ~ f^2 / 12 and the
  // bilinear interpolation ~ f^2 / 6 leave sigma^2 - f^2 / 4 to the Gaussian.
  const double small_sigma = std::sqrt(sigma_px * sigma_px - f * f / 4.0) / f;
  cv::GaussianBlur(small, small, cv::Size(0, 0), small_sigma, small_sigma, cv::BORDER_REFLECT);
  cv::resize(small, out, image.size(), 0.0, 0.0, cv::INTER_LINEAR);
  return out;
}

cv::Mat HighPassImage(const cv::Mat& intensity, double sigma_px) {
  const cv::Mat grey = NormaliseImage(intensity, Normalisation::kNone);
  if (grey.empty() || !(sigma_px > 0.0)) return grey;
  const cv::Mat local_mean = GaussianBlurAnyWidth(grey, sigma_px);
  const cv::Mat difference = grey - local_mean;
  double lowest = 0.0, highest = 0.0;
  cv::minMaxLoc(difference, &lowest, &highest);
  cv::Mat out;
  if (!(highest - lowest > 1e-9)) {
    out = cv::Mat(grey.size(), CV_32FC1, cv::Scalar(0.5));
  } else {
    difference.convertTo(out, CV_32F, 1.0 / (highest - lowest), -lowest / (highest - lowest));
  }
  return out;
}

}  // namespace scenecal
