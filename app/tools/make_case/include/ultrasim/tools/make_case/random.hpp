#pragma once

// Random numbers for the case generator, implemented here rather than taken from <random>: the
// standard fixes the engines' sequences but not the distributions', so std::*_distribution may
// give other numbers with another standard library, and the generated case would change.
// Everything here is integer arithmetic plus one std::log / std::sqrt per sample.

#include <cmath>
#include <cstdint>

namespace ultrasim::tools {

// SplitMix64 step (Vigna): a good 64-bit mixer. Used to seed Xoshiro256 and to hash coordinates
// into reproducible per-cell random values. Pure; never allocates.
constexpr std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// A random 64-bit value fixed by (seed, a, b, c): the same cell always gets the same value,
// whatever order cells are visited in.
constexpr std::uint64_t hash64(std::uint64_t seed, std::int64_t a, std::int64_t b = 0,
                               std::int64_t c = 0) {
  std::uint64_t s = seed;
  s ^= splitmix64(s) + static_cast<std::uint64_t>(a);
  s ^= splitmix64(s) + static_cast<std::uint64_t>(b);
  s ^= splitmix64(s) + static_cast<std::uint64_t>(c);
  return splitmix64(s);
}

// The top 53 bits of `bits` as a double in [0, 1).
constexpr double unit_from_bits(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

// xoshiro256** (Blackman & Vigna 2018): fast, 256-bit state, passes BigCrush. Seeded from one
// 64-bit value through SplitMix64 as its authors recommend. Not thread-safe; never allocates.
class Xoshiro256 {
 public:
  explicit constexpr Xoshiro256(std::uint64_t seed) {
    for (auto& word : s_) word = splitmix64(seed);
  }

  constexpr std::uint64_t next() {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // Uniform in [0, 1), 53 random bits.
  constexpr double uniform() { return unit_from_bits(next()); }

 private:
  static constexpr std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t s_[4] = {};
};

// Inverse CDF of the Rayleigh distribution with scale `sigma`: F(r) = 1 − exp(−r² / 2σ²), so
// r = σ·sqrt(−2·ln(1 − u)) for u uniform in [0, 1). Mean σ·sqrt(π/2) ≈ 1.2533σ, standard
// deviation σ·sqrt((4 − π)/2) ≈ 0.6551σ, mean/std ≈ 1.913 whatever σ.
inline double rayleigh_from_uniform(double u, double sigma = 1.0) {
  return sigma * std::sqrt(-2.0 * std::log1p(-u));
}

// Mean of a Rayleigh variable of scale 1: sqrt(π/2).
inline constexpr double kRayleighMean = 1.2533141373155001;

}  // namespace ultrasim::tools
