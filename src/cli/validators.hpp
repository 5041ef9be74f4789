// Number checks for CLI options whose messages say what was expected (CLI11's
// own PositiveNumber prints the whole range of a double).
#pragma once

#include <cmath>
#include <exception>
#include <regex>
#include <string>

#include <CLI/CLI.hpp>

namespace scenecal::cli {

namespace detail {
// The whole of `text` as a finite number >= 0; false for anything else (a sign, a suffix, NaN).
inline bool ParseNonNegativeNumber(const std::string& text, double* value) {
  std::size_t used = 0;
  try {
    *value = std::stod(text, &used);
  } catch (const std::exception&) {
    return false;
  }
  return !text.empty() && used == text.size() && std::isfinite(*value) && *value >= 0.0;
}

inline CLI::Validator NumberCheck(bool allow_zero, const char* name, const char* expected) {
  return CLI::Validator(
      [allow_zero, expected](std::string& input) -> std::string {
        double value = 0.0;
        const bool valid = ParseNonNegativeNumber(input, &value) && (allow_zero || value > 0.0);
        return valid ? std::string() : input + " is not " + expected;
      },
      name);
}
}  // namespace detail

// A finite number > 0.
inline const CLI::Validator kPositive = detail::NumberCheck(false, "POSITIVE", "a positive number");
// A finite number >= 0.
inline const CLI::Validator kNonNegative = detail::NumberCheck(true, "NONNEGATIVE", "a number >= 0");

// A number of pixels >= 0, or N% (0 <= N <= 50) of an image's width.
inline const CLI::Validator kPixelsOrPercent(
    [](std::string& input) -> std::string {
      const bool percent = !input.empty() && input.back() == '%';
      const std::string number = percent ? input.substr(0, input.size() - 1) : input;
      double value = 0.0;
      if (!detail::ParseNonNegativeNumber(number, &value) || (percent && value > 50.0)) {
        return input + " is not a number of pixels >= 0 or a percentage N% with 0 <= N <= 50";
      }
      return {};
    },
    "PIXELS|N%");

// An image size WxH (e.g. 640x480), each side 1 to 5 digits.
inline bool ParseImageSize(const std::string& text, int* width, int* height) {
  std::smatch match;
  static const std::regex pattern(R"(^(\d{1,5})[xX](\d{1,5})$)");
  if (!std::regex_match(text, match, pattern)) return false;
  *width = std::stoi(match[1]);
  *height = std::stoi(match[2]);
  return true;
}
inline const CLI::Validator kImageSize(
    [](std::string& input) -> std::string {
      int width = 0;
      int height = 0;
      return ParseImageSize(input, &width, &height) ? std::string() : input + " is not WxH (e.g. 640x480)";
    },
    "WxH");

}  // namespace scenecal::cli
