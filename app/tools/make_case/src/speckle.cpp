#include "ultrasim/tools/make_case/speckle.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <stdexcept>

#include "ultrasim/tools/make_case/random.hpp"

namespace ultrasim::tools {

namespace {

// Sampled Gaussian with radius ceil(3σ); a σ under a fifth of a voxel is no blur at all.
std::vector<float> gaussian_weights(double sigma_vox) {
  if (sigma_vox < 0.2) return {1.0f};
  const int radius = static_cast<int>(std::ceil(3.0 * sigma_vox));
  std::vector<float> w(static_cast<std::size_t>(2 * radius + 1));
  for (int t = -radius; t <= radius; ++t) {
    w[static_cast<std::size_t>(t + radius)] =
        static_cast<float>(std::exp(-0.5 * (t * t) / (sigma_vox * sigma_vox)));
  }
  return w;
}

// Normaliser for each position along an axis of length n: uses only the weights that land
// inside the volume, so the faces are neither darker nor brighter than the middle.
std::vector<float> position_scale(const std::vector<float>& w, int n, KernelNorm norm) {
  const int radius = static_cast<int>(w.size() / 2);
  std::vector<float> scale(static_cast<std::size_t>(n));
  for (int p = 0; p < n; ++p) {
    double s = 0.0;
    for (int t = -radius; t <= radius; ++t) {
      if (p + t < 0 || p + t >= n) continue;
      const double wt = w[static_cast<std::size_t>(t + radius)];
      s += norm == KernelNorm::kUnitEnergy ? wt * wt : wt;
    }
    scale[static_cast<std::size_t>(p)] =
        static_cast<float>(norm == KernelNorm::kUnitEnergy ? 1.0 / std::sqrt(s) : 1.0 / s);
  }
  return scale;
}

// One separable pass along `axis` (0 = x, 1 = y, 2 = z). `src` is a copy of `field`.
void blur_axis(std::span<float> field, std::span<const float> src, const Eigen::Vector3i& size,
               int axis, const std::vector<float>& w, const std::vector<float>& scale) {
  const int nx = size.x(), ny = size.y(), nz = size.z();
  const int radius = static_cast<int>(w.size() / 2);
  const auto row_offset = [&](int j, int k) {
    return static_cast<std::size_t>(nx) *
           (static_cast<std::size_t>(j) +
            static_cast<std::size_t>(ny) * static_cast<std::size_t>(k));
  };
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      float* out = field.data() + row_offset(j, k);
      if (axis == 0) {
        const float* in = src.data() + row_offset(j, k);
        for (int i = 0; i < nx; ++i) {
          const int t0 = std::max(-radius, -i), t1 = std::min(radius, nx - 1 - i);
          float acc = 0.0f;
          for (int t = t0; t <= t1; ++t) acc += w[static_cast<std::size_t>(t + radius)] * in[i + t];
          out[i] = acc * scale[static_cast<std::size_t>(i)];
        }
        continue;
      }
      // y and z: whole rows at a time, so the inner loop runs along contiguous x.
      const int pos = axis == 1 ? j : k;
      const int n = axis == 1 ? ny : nz;
      std::fill(out, out + nx, 0.0f);
      for (int t = std::max(-radius, -pos); t <= std::min(radius, n - 1 - pos); ++t) {
        const float wt = w[static_cast<std::size_t>(t + radius)];
        const float* in = src.data() + (axis == 1 ? row_offset(j + t, k) : row_offset(j, k + t));
        for (int i = 0; i < nx; ++i) out[i] += wt * in[i];
      }
      const float s = scale[static_cast<std::size_t>(pos)];
      for (int i = 0; i < nx; ++i) out[i] *= s;
    }
  }
}

}  // namespace

void blur_with_psf(std::span<float> field, const Eigen::Vector3i& size,
                   const Eigen::Vector3d& spacing_mm, const PsfSettings& psf, KernelNorm norm) {
  if (field.size() != static_cast<std::size_t>(size.prod())) {
    throw std::invalid_argument("blur_with_psf: field size does not match the grid");
  }
  const double sigma_mm[3] = {psf.lateral_sigma_mm, psf.elevation_sigma_mm, psf.axial_sigma_mm};
  std::vector<float> scratch(field.size());
  for (int axis = 0; axis < 3; ++axis) {
    const auto w = gaussian_weights(sigma_mm[axis] / spacing_mm[axis]);
    if (w.size() == 1) continue;
    std::copy(field.begin(), field.end(), scratch.begin());
    blur_axis(field, scratch, size, axis, w, position_scale(w, size[axis], norm));
  }
}

std::vector<float> speckle_pattern(const Eigen::Vector3i& size, const Eigen::Vector3d& spacing_mm,
                                   const PsfSettings& psf, std::uint64_t seed) {
  if ((size.array() <= 0).any()) throw std::invalid_argument("speckle_pattern: empty grid");
  const std::size_t n = static_cast<std::size_t>(size.prod());
  // In-phase and quadrature parts of the scattered field: r·(cos θ, sin θ) with r Rayleigh and
  // θ uniform has unit variance per part (the Box–Muller pair).
  std::vector<float> in_phase(n), quadrature(n);
  Xoshiro256 rng(seed);
  for (std::size_t v = 0; v < n; ++v) {
    const double r = rayleigh_from_uniform(rng.uniform());
    const double theta = 2.0 * std::numbers::pi * rng.uniform();
    in_phase[v] = static_cast<float>(r * std::cos(theta));
    quadrature[v] = static_cast<float>(r * std::sin(theta));
  }
  blur_with_psf(in_phase, size, spacing_mm, psf, KernelNorm::kUnitEnergy);
  blur_with_psf(quadrature, size, spacing_mm, psf, KernelNorm::kUnitEnergy);
  // Unit-variance parts give a unit-scale Rayleigh envelope; divide by its mean.
  constexpr float kInvMean = static_cast<float>(1.0 / kRayleighMean);
  for (std::size_t v = 0; v < n; ++v) {
    in_phase[v] = std::sqrt(in_phase[v] * in_phase[v] + quadrature[v] * quadrature[v]) * kInvMean;
  }
  return in_phase;
}

double rayleigh_power_mean(double gamma) {
  // S = R / sqrt(π/2) with R of unit scale; E[R^γ] = 2^(γ/2)·Γ(1 + γ/2).
  return std::pow(2.0, gamma / 2.0) * std::tgamma(1.0 + gamma / 2.0) /
         std::pow(kRayleighMean, gamma);
}

}  // namespace ultrasim::tools
