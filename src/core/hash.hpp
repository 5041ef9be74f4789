// A stateless 64-bit mix for keyed pseudo-random choices: the same key gives
// the same bits on every thread, rank and run (the simulator's noise, the
// swathe thinning).
#pragma once

#include <cstdint>

namespace scenecal {

// SplitMix64 finaliser: a strong 64-bit mix.
constexpr std::uint64_t Mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

}  // namespace scenecal
