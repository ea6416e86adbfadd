#pragma once

#include <span>

#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// The Reuss average of a mixture of isotropic tissues: 1/K = Σ fᵢ/Kᵢ and 1/G = Σ fᵢ/Gᵢ over the
// bulk and shear moduli (uniform stress in every phase), returned as E and ν; the stiffening is
// the volume average. The label and name are the largest phase's (the first of equals).
// volume_fractions ≥ 0, one per phase, summing to > 0 (normalised here). A single phase (or one
// with every fraction) comes back unchanged, bit for bit. Throws std::invalid_argument for
// mismatched or empty inputs.
Material reuss_average(std::span<const Material> phases, std::span<const double> volume_fractions);

}  // namespace ultrasim::sim
