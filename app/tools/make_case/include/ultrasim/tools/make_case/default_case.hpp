#pragma once

// The embedded default case: the synthetic upper arm of arm_phantom.hpp rendered into a B-mode
// echo volume (speckle, shadows, enhancement) and an exact label volume on one regular grid.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>

#include "ultrasim/imaging/volume.hpp"
#include "ultrasim/tools/make_case/arm_phantom.hpp"
#include "ultrasim/tools/make_case/case_toml.hpp"
#include "ultrasim/tools/make_case/speckle.hpp"

namespace ultrasim::tools {

struct DefaultCaseSettings {
  double spacing_mm = 0.25;  // isotropic voxel size; 0.25 mm gives 241×161×181 voxels
  Eigen::Vector3d min_mm{-30.0, -20.0, 0.0};  // first voxel centre (patient space)
  Eigen::Vector3d max_mm{30.0, 20.0, 45.0};   // last voxel centre, rounded to the spacing
  ArmAnatomy anatomy;
  PsfSettings psf;
  std::uint64_t speckle_seed = 0x0517ca5e;  // fixes the speckle pattern
  // Grey = mean echo · S^γ / E[S^γ] with S the Rayleigh speckle pattern. γ = 1 is the raw
  // envelope; γ < 1 mimics the log compression of a scanner's display (less contrasty speckle)
  // while each tissue keeps its mean brightness.
  double speckle_exponent = 0.5;
};

// Grey levels the beam effects use (also used by tests).
inline constexpr float kShadowGrey = 6.0f;         // below the bone's cortical echo
inline constexpr double kEnhancementPerMm = 0.05;  // extra gain per mm of blood above a point
inline constexpr double kMaxEnhancement = 1.45;    // cap on that gain

struct GeneratedCase {
  imaging::Volume<std::uint8_t> echo;    // B-mode echo intensities
  imaging::Volume<std::uint8_t> labels;  // tissue labels, exact (nearest, no blur)
};

// Renders the default case. Deterministic: the same settings give the same voxels on every run
// and every standard library (own PRNG, no std distributions). Allocates ~25 bytes per voxel
// while it works (≈170 MB at 0.25 mm); about 2 s at 0.25 mm on one core.
GeneratedCase generate_default_case(const DefaultCaseSettings& settings = {});

// Writes <dir>/volume.mha, <dir>/labels.mha (zlib MetaImage) and <dir>/case.toml, creating
// `dir` if needed. Throws imaging::MetaImageError or std::runtime_error on I/O failure.
// `layout` names the case and lays out its mesh and scan (default: the default case's).
void write_case_folder(const std::filesystem::path& dir, const GeneratedCase& generated,
                       const ArmCaseLayout& layout = {});

}  // namespace ultrasim::tools
