#pragma once

// Ultrasound speckle for the synthetic case: a field of random scatterers imaged through a
// Gaussian point-spread function, as in the standard "complex baseband" model of B-mode images.
// The envelope of a sum of many random phasors is Rayleigh distributed, so homogeneous tissue
// shows Rayleigh speckle whose grain has the PSF's size (elongated laterally, short axially).

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace ultrasim::tools {

// Gaussian PSF of the simulated scanner, standard deviations in mm. Defaults are those of a
// ~10 MHz linear array: axial FWHM ≈ 0.4 mm, lateral ≈ 0.9 mm, elevation (slice) ≈ 1.3 mm
// (FWHM = 2.355 σ). Wider σ: coarser, smoother speckle and softer edges; cost grows with σ.
struct PsfSettings {
  double lateral_sigma_mm = 0.38;    // along x (the array)
  double elevation_sigma_mm = 0.55;  // along y (slice thickness)
  double axial_sigma_mm = 0.16;      // along z (the beam)
};

// How a blur kernel is normalised.
enum class KernelNorm {
  kUnitEnergy,  // Σw² = 1: keeps the variance of uncorrelated noise (the scatterer field)
  kUnitSum,     // Σw = 1: keeps the mean of a smooth field (coherent, specular echoes)
};

// Blurs a volume (x fastest, then y, then z) in place with the separable Gaussian PSF. Near the
// volume's faces the weights that fall outside are dropped and the rest renormalised, so
// statistics hold right up to the edge. Allocates one scratch copy of the field.
void blur_with_psf(std::span<float> field, const Eigen::Vector3i& size,
                   const Eigen::Vector3d& spacing_mm, const PsfSettings& psf, KernelNorm norm);

// Unit speckle pattern: each voxel scatters r·(cos θ, sin θ) with r Rayleigh (inverse CDF) and θ
// uniform (a circular complex Gaussian), the complex field is blurred with the unit-energy PSF,
// and its envelope |·| is divided by the Rayleigh mean sqrt(π/2). The result is Rayleigh
// distributed with mean 1 and mean/std ≈ 1.91, correlated over the PSF's extent; multiplying it
// by a tissue's mean echo gives that tissue's speckle. Deterministic for a given seed. Allocates
// the result and one more field of the same size (8 bytes per voxel).
std::vector<float> speckle_pattern(const Eigen::Vector3i& size, const Eigen::Vector3d& spacing_mm,
                                   const PsfSettings& psf, std::uint64_t seed);

// E[S^γ] for S Rayleigh with mean 1: the factor that keeps a tissue's mean brightness when the
// speckle is compressed as S^γ (γ = 1: 1). Pure.
double rayleigh_power_mean(double gamma);

}  // namespace ultrasim::tools
