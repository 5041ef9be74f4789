// Number checks for CLI options whose messages say what was expected (CLI11's
// own PositiveNumber prints the whole range of a double).
#pragma once

#include <cmath>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

namespace scenecal::cli {

namespace detail {
inline CLI::Validator NumberCheck(bool allow_zero, const char* name, const char* expected) {
  return CLI::Validator(
      [allow_zero, expected](std::string& input) -> std::string {
        double value = 0.0;
        std::size_t used = 0;
        try {
          value = std::stod(input, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used != input.size() || !std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0))
          return input + " is not " + expected;
        return {};
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
      std::size_t used = 0;
      try {
        value = std::stod(number, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (number.empty() || used != number.size() || !std::isfinite(value) || value < 0.0 ||
          (percent && value > 50.0)) {
        return input + " is not a number of pixels >= 0 or a percentage N% with 0 <= N <= 50";
      }
      return {};
    },
    "PIXELS|N%");

}  // namespace scenecal::cli
