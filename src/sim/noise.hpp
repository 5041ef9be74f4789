// Counter-based random numbers and procedural noise for the simulator.
//
// Every random quantity is a pure function of a key (seed, stream, frame,
// pixel or beam, ...), never the state of a shared generator, so the output
// does not depend on the order in which threads run.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hash.hpp"

namespace scenecal::sim {

// Hash of a key made of several integers.
constexpr std::uint64_t HashKey(std::uint64_t a, std::uint64_t b = 0, std::uint64_t c = 0, std::uint64_t d = 0) {
  return Mix64(Mix64(Mix64(Mix64(a) ^ b) ^ c) ^ d);
}

// Uniform in [0, 1) from a hash (53 bits).
inline double UniformFromHash(std::uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

// Standard normal from a hash (Box-Muller on two derived uniforms).
inline double GaussianFromHash(std::uint64_t h) {
  const double u1 = UniformFromHash(Mix64(h ^ 0xA5A5A5A5A5A5A5A5ULL)) + 0x1.0p-54;  // (0, 1)
  const double u2 = UniformFromHash(Mix64(h ^ 0x5A5A5A5A5A5A5A5AULL));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

// A small deterministic generator for building the world and the motion
// (single-threaded code only); each draw hashes (seed, stream, counter).
class KeyedRandom {
 public:
  KeyedRandom(std::uint64_t seed, std::uint64_t stream) : seed_(seed), stream_(stream) {}
  double Uniform() { return UniformFromHash(HashKey(seed_, stream_, counter_++)); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  double Gaussian() { return GaussianFromHash(HashKey(seed_, stream_, counter_++, 1)); }
  bool Chance(double probability) { return Uniform() < probability; }
  int Integer(int lo, int hi_inclusive) {
    return lo + static_cast<int>(Uniform() * (hi_inclusive - lo + 1) * 0.999999999);
  }

 private:
  std::uint64_t seed_, stream_, counter_ = 0;
};

// Lattice value noise in [-1, 1], smooth (quintic fade), keyed by a seed.
// One mix of the lattice coordinates folded with large odd multipliers (cheap:
// textures evaluate it millions of times per image).
inline double LatticeValue(std::uint64_t seed, std::int64_t ix, std::int64_t iy, std::int64_t iz = 0) {
  const std::uint64_t key = seed ^ (static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ULL) ^
                            (static_cast<std::uint64_t>(iy) * 0xC2B2AE3D27D4EB4FULL) ^
                            (static_cast<std::uint64_t>(iz) * 0x165667B19E3779F9ULL);
  return 2.0 * UniformFromHash(Mix64(key)) - 1.0;
}

inline double Fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

inline double ValueNoise2(std::uint64_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const double tx = Fade(x - fx), ty = Fade(y - fy);
  const double v00 = LatticeValue(seed, ix, iy), v10 = LatticeValue(seed, ix + 1, iy);
  const double v01 = LatticeValue(seed, ix, iy + 1), v11 = LatticeValue(seed, ix + 1, iy + 1);
  const double a = v00 + (v10 - v00) * tx, b = v01 + (v11 - v01) * tx;
  return a + (b - a) * ty;
}

inline double ValueNoise3(std::uint64_t seed, double x, double y, double z) {
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy),
             iz = static_cast<std::int64_t>(fz);
  const double tx = Fade(x - fx), ty = Fade(y - fy), tz = Fade(z - fz);
  double layer[2];
  for (int k = 0; k < 2; ++k) {
    const double v00 = LatticeValue(seed, ix, iy, iz + k), v10 = LatticeValue(seed, ix + 1, iy, iz + k);
    const double v01 = LatticeValue(seed, ix, iy + 1, iz + k), v11 = LatticeValue(seed, ix + 1, iy + 1, iz + k);
    const double a = v00 + (v10 - v00) * tx, b = v01 + (v11 - v01) * tx;
    layer[k] = a + (b - a) * ty;
  }
  return layer[0] + (layer[1] - layer[0]) * tz;
}

// Fractal sum of octaves (each half the amplitude, twice the frequency),
// roughly in [-1, 1].
inline double Fbm2(std::uint64_t seed, double x, double y, int octaves) {
  double sum = 0.0, amplitude = 0.5, norm = 0.0;
  for (int o = 0; o < octaves; ++o) {
    sum += amplitude * ValueNoise2(seed + static_cast<std::uint64_t>(o) * 7919, x, y);
    norm += amplitude;
    amplitude *= 0.5;
    x *= 2.03;
    y *= 2.03;
  }
  return sum / norm;
}

}  // namespace scenecal::sim
