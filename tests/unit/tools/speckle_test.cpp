// Speckle: the generated pattern is Rayleigh distributed (mean 1, mean/std ≈ 1.91) before and
// after the PSF, and the PSF blur keeps what its normalisation promises, up to the faces.

#include "ultrasim/tools/make_case/speckle.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

namespace ultrasim::tools {
namespace {

struct Moments {
  double mean = 0.0;
  double sd = 0.0;
};

Moments moments(const std::vector<float>& v) {
  double s = 0.0, s2 = 0.0;
  for (const float x : v) {
    s += x;
    s2 += static_cast<double>(x) * x;
  }
  const double mean = s / static_cast<double>(v.size());
  return {mean, std::sqrt(s2 / static_cast<double>(v.size()) - mean * mean)};
}

const Eigen::Vector3i kSize(96, 64, 48);
const Eigen::Vector3d kSpacing(0.25, 0.25, 0.25);

TEST(Speckle, UnblurredPatternIsRayleigh) {
  const PsfSettings no_blur{0.0, 0.0, 0.0};
  const auto m = moments(speckle_pattern(kSize, kSpacing, no_blur, 99));
  EXPECT_NEAR(m.mean, 1.0, 0.01);
  EXPECT_NEAR(m.mean / m.sd, 1.913, 0.02);
}

TEST(Speckle, BlurredPatternStaysRayleigh) {
  // Blurring the complex field (not the envelope) keeps it circular Gaussian, so the envelope
  // is still Rayleigh; samples are correlated, hence the wider tolerance.
  const auto m = moments(speckle_pattern(kSize, kSpacing, PsfSettings{}, 99));
  EXPECT_NEAR(m.mean, 1.0, 0.02);
  EXPECT_NEAR(m.mean / m.sd, 1.913, 0.06);
}

TEST(Speckle, SameSeedSamePattern) {
  const Eigen::Vector3i size(20, 10, 8);
  EXPECT_EQ(speckle_pattern(size, kSpacing, PsfSettings{}, 5),
            speckle_pattern(size, kSpacing, PsfSettings{}, 5));
  EXPECT_NE(speckle_pattern(size, kSpacing, PsfSettings{}, 5),
            speckle_pattern(size, kSpacing, PsfSettings{}, 6));
}

TEST(Speckle, UnitSumBlurKeepsAConstantFieldEverywhere) {
  const Eigen::Vector3i size(12, 9, 7);
  std::vector<float> field(static_cast<std::size_t>(size.prod()), 42.0f);
  blur_with_psf(field, size, kSpacing, PsfSettings{}, KernelNorm::kUnitSum);
  for (const float v : field) EXPECT_NEAR(v, 42.0f, 1e-3f);
}

TEST(Speckle, PowerMeanKeepsTissueBrightness) {
  EXPECT_NEAR(rayleigh_power_mean(1.0), 1.0, 1e-12);
  // E[S²] for mean-1 Rayleigh S: 4/π.
  EXPECT_NEAR(rayleigh_power_mean(2.0), 4.0 / std::numbers::pi, 1e-12);
  const auto s = speckle_pattern(kSize, kSpacing, PsfSettings{}, 3);
  double sum = 0.0;
  for (const float v : s) sum += std::sqrt(v);
  EXPECT_NEAR(sum / static_cast<double>(s.size()), rayleigh_power_mean(0.5), 0.01);
}

}  // namespace
}  // namespace ultrasim::tools
