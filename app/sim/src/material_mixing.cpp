#include "ultrasim/sim/material_mixing.hpp"

#include <stdexcept>

namespace ultrasim::sim {

Material reuss_average(std::span<const Material> phases, std::span<const double> volume_fractions) {
  if (phases.empty() || phases.size() != volume_fractions.size()) {
    throw std::invalid_argument("reuss_average: one volume fraction per phase, at least one phase");
  }
  double total = 0.0;
  std::size_t largest = 0;
  int present = 0;
  for (std::size_t i = 0; i < phases.size(); ++i) {
    if (!(volume_fractions[i] >= 0.0)) {
      throw std::invalid_argument("reuss_average: volume fractions must be >= 0");
    }
    total += volume_fractions[i];
    present += volume_fractions[i] > 0.0;
    if (volume_fractions[i] > volume_fractions[largest]) largest = i;
  }
  if (!(total > 0.0)) throw std::invalid_argument("reuss_average: volume fractions sum to 0");
  if (present == 1) return phases[largest];

  double bulk_compliance = 0.0, shear_compliance = 0.0, stiffening = 0.0;
  for (std::size_t i = 0; i < phases.size(); ++i) {
    const double f = volume_fractions[i] / total;
    const double e = phases[i].youngs_modulus_kpa, nu = phases[i].poisson_ratio;
    bulk_compliance += f * 3.0 * (1.0 - 2.0 * nu) / e;  // 1/K
    shear_compliance += f * 2.0 * (1.0 + nu) / e;       // 1/G
    stiffening += f * phases[i].stiffening;
  }
  const double k = 1.0 / bulk_compliance, g = 1.0 / shear_compliance;
  Material mixed = phases[largest];
  mixed.youngs_modulus_kpa = 9.0 * k * g / (3.0 * k + g);
  mixed.poisson_ratio = (3.0 * k - 2.0 * g) / (2.0 * (3.0 * k + g));
  mixed.stiffening = stiffening;
  return mixed;
}

}  // namespace ultrasim::sim
