#include "core/normalisation.hpp"

#include <algorithm>
#include <cmath>

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

cv::Mat HighPassImage(const cv::Mat& intensity, double sigma_px) {
  const cv::Mat grey = NormaliseImage(intensity, Normalisation::kNone);
  if (grey.empty() || !(sigma_px > 0.0)) return grey;
  cv::Mat local_mean;
  cv::GaussianBlur(grey, local_mean, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REFLECT);
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
