#pragma once

#include <Eigen/Core>

#include "ultrasim/sim/settings.hpp"

namespace ultrasim::sim {

// The strain energy of a hyperelastic tissue: a compressible neo-Hookean solid whose distortion
// energy may stiffen exponentially, in the manner of Demiray (1972) and Fung's soft-tissue laws:
//
//   W = I₁ − 3 − 2 ln J   (I₁ = tr FᵀF, J = det F; W ≥ 0, and 0 only for rotations)
//   Ψ = μ/(2γ) (exp(γ W) − 1) + λ/2 (ln J)²,   γ = 0:  Ψ = μ/2 W + λ/2 (ln J)²
//
// μ, λ are the Lamé constants of the material's E and ν, so at small strain the law is the linear
// elasticity of LinearFem (dW/dF = 0 at F = I, whatever γ): the same stiffness at rest, different
// answers only under large strain. γ (Material::stiffening) is how fast tissue stiffens as it is
// squeezed: 0 is neo-Hookean. The ln J term makes a tet's energy grow without bound as its volume
// goes to zero, so a solution never inverts a tet: a collapsing lumen closes, it cannot turn
// inside out.
//
// Units: kPa; energy density in kPa = µJ/mm³.
struct HyperelasticLaw {
  double mu_kpa = 0.0;
  double lambda_kpa = 0.0;
  double stiffening = 0.0;  // γ, dimensionless

  static HyperelasticLaw of(const Material& m);

  // Ψ(F). +infinity when det F ≤ 0 or the exponential overflows: no finite energy there.
  double energy_density_kpa(const Eigen::Matrix3d& f) const;
  // First Piola–Kirchhoff stress P = ∂Ψ/∂F (det F > 0).
  Eigen::Matrix3d first_piola_kpa(const Eigen::Matrix3d& f) const;
  // ∂P/∂F over column-major vec(F): entry (i + 3j, k + 3l) = ∂P_ij/∂F_kl (det F > 0).
  Eigen::Matrix<double, 9, 9> stress_derivative_kpa(const Eigen::Matrix3d& f) const;
};

}  // namespace ultrasim::sim
