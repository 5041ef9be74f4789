// Shared by the libFuzzer harnesses: run a parser on the input, accept
// io::InputError (the promised answer to bad input) and let anything else
// escape, so that libFuzzer reports it (an uncaught exception aborts). Checks
// on what a parser accepted abort with a message.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <Eigen/Geometry>

#include "io/error.hpp"

namespace scenecal::fuzz {

[[noreturn]] inline void Violated(const char* what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what);
  std::abort();
}

inline void Check(bool condition, const char* what) {
  if (!condition) Violated(what);
}

inline bool IsFinite(const Eigen::Isometry3d& transform) { return transform.matrix().allFinite(); }

template <typename Parse>
int RunParser(const std::uint8_t* data, std::size_t size, Parse parse) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  try {
    parse(input);
  } catch (const io::InputError& e) {
    // SCENECAL_FUZZ_VERBOSE=1: show why an input was refused (checking seeds).
    static const bool verbose = std::getenv("SCENECAL_FUZZ_VERBOSE") != nullptr;
    if (verbose) std::fprintf(stderr, "InputError: %s\n", e.what());
  }
  return 0;
}

}  // namespace scenecal::fuzz
