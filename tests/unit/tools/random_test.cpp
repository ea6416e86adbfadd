// The case generator's own PRNG and Rayleigh sampler: fixed sequences (so the case is the same
// with every standard library) and the right distribution.

#include "ultrasim/tools/make_case/random.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace ultrasim::tools {
namespace {

// Reference values from an independent Python implementation of SplitMix64 / xoshiro256**;
// splitmix64 from state 0 giving 0xe220a8397b1dcdaf is the published reference.
TEST(Random, SplitMix64MatchesReference) {
  std::uint64_t state = 0;
  EXPECT_EQ(splitmix64(state), 0xe220a8397b1dcdafULL);
}

TEST(Random, Xoshiro256MatchesReference) {
  Xoshiro256 zero(0);
  EXPECT_EQ(zero.next(), 0x99ec5f36cb75f2b4ULL);
  EXPECT_EQ(zero.next(), 0xbf6e1f784956452aULL);
  EXPECT_EQ(zero.next(), 0x1a5f849d4933e6e0ULL);
  Xoshiro256 other(12345);
  EXPECT_EQ(other.next(), 0xbe6a36374160d49bULL);
  EXPECT_EQ(other.next(), 0x214aaa0637a688c6ULL);
  EXPECT_EQ(other.next(), 0xf69d16de9954d388ULL);
}

TEST(Random, UniformStaysInUnitInterval) {
  EXPECT_EQ(unit_from_bits(0), 0.0);
  EXPECT_LT(unit_from_bits(~std::uint64_t{0}), 1.0);
  Xoshiro256 rng(7);
  double sum = 0.0;
  constexpr int kN = 100000;
  for (int n = 0; n < kN; ++n) sum += rng.uniform();
  EXPECT_NEAR(sum / kN, 0.5, 0.005);
}

TEST(Random, RayleighInverseCdfIsExact) {
  EXPECT_EQ(rayleigh_from_uniform(0.0), 0.0);
  // F(σ) = 1 − e^(−1/2), F(2σ) = 1 − e^(−2).
  EXPECT_NEAR(rayleigh_from_uniform(1.0 - std::exp(-0.5), 3.0), 3.0, 1e-12);
  EXPECT_NEAR(rayleigh_from_uniform(1.0 - std::exp(-2.0)), 2.0, 1e-12);
}

TEST(Random, RayleighSamplesHaveRayleighStatistics) {
  Xoshiro256 rng(2013);
  constexpr int kN = 200000;
  std::vector<double> r(kN);
  double sum = 0.0, sum2 = 0.0;
  for (auto& v : r) {
    v = rayleigh_from_uniform(rng.uniform());
    sum += v;
    sum2 += v * v;
  }
  const double mean = sum / kN;
  const double sd = std::sqrt(sum2 / kN - mean * mean);
  EXPECT_NEAR(mean, kRayleighMean, 0.005);
  EXPECT_NEAR(mean / sd, 1.9131, 0.01);  // sqrt(π / (4 − π))
  // Kolmogorov–Smirnov distance to F(r) = 1 − exp(−r²/2); 1.63/sqrt(N) is the 1 % level.
  std::sort(r.begin(), r.end());
  double ks = 0.0;
  for (int n = 0; n < kN; ++n) {
    const double f = 1.0 - std::exp(-0.5 * r[n] * r[n]);
    ks = std::max({ks, std::abs(f - static_cast<double>(n) / kN),
                   std::abs(f - static_cast<double>(n + 1) / kN)});
  }
  EXPECT_LT(ks, 1.63 / std::sqrt(kN));
}

TEST(Random, Hash64IsAFunctionOfItsArguments) {
  EXPECT_EQ(hash64(1, 2, 3, 4), hash64(1, 2, 3, 4));
  EXPECT_NE(hash64(1, 2, 3, 4), hash64(1, 2, 4, 3));
  EXPECT_NE(hash64(1, 2, 3, 4), hash64(2, 2, 3, 4));
}

}  // namespace
}  // namespace ultrasim::tools
