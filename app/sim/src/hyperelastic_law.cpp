#include "ultrasim/sim/hyperelastic_law.hpp"

#include <Eigen/LU>
#include <cmath>
#include <limits>

namespace ultrasim::sim {

namespace {

// exp(γ W) above this is treated as no finite energy: e^700 is near double's limit.
constexpr double kMaxExponent = 700.0;

// W = I₁ − 3 − 2 ln J and the exponential factor e = exp(γ W) (1 when γ = 0).
struct Distortion {
  double w = 0.0;
  double factor = 1.0;
};

Distortion distortion(const HyperelasticLaw& law, const Eigen::Matrix3d& f, double log_j) {
  Distortion d;
  d.w = f.squaredNorm() - 3.0 - 2.0 * log_j;
  d.factor = law.stiffening > 0.0 ? std::exp(std::min(law.stiffening * d.w, kMaxExponent)) : 1.0;
  return d;
}

}  // namespace

HyperelasticLaw HyperelasticLaw::of(const Material& m) {
  const double e = m.youngs_modulus_kpa, nu = m.poisson_ratio;
  HyperelasticLaw law;
  law.mu_kpa = e / (2.0 * (1.0 + nu));
  law.lambda_kpa = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  law.stiffening = m.stiffening;
  return law;
}

double HyperelasticLaw::energy_density_kpa(const Eigen::Matrix3d& f) const {
  const double j = f.determinant();
  if (!(j > 0.0)) return std::numeric_limits<double>::infinity();
  const double log_j = std::log(j);
  const Distortion d = distortion(*this, f, log_j);
  if (stiffening > 0.0 && stiffening * d.w >= kMaxExponent) {
    return std::numeric_limits<double>::infinity();
  }
  const double shape = stiffening > 0.0 ? mu_kpa / (2.0 * stiffening) * std::expm1(stiffening * d.w)
                                        : 0.5 * mu_kpa * d.w;
  return shape + 0.5 * lambda_kpa * log_j * log_j;
}

Eigen::Matrix3d HyperelasticLaw::first_piola_kpa(const Eigen::Matrix3d& f) const {
  const double j = f.determinant();
  const double log_j = std::log(j);
  const Eigen::Matrix3d f_inv_t = f.inverse().transpose();
  const Distortion d = distortion(*this, f, log_j);
  // ∂W/∂F = 2 (F − F⁻ᵀ), ∂(ln J)/∂F = F⁻ᵀ.
  return mu_kpa * d.factor * (f - f_inv_t) + lambda_kpa * log_j * f_inv_t;
}

Eigen::Matrix<double, 9, 9> HyperelasticLaw::stress_derivative_kpa(const Eigen::Matrix3d& f) const {
  const double j = f.determinant();
  const double log_j = std::log(j);
  const Eigen::Matrix3d g = f.inverse().transpose();  // F⁻ᵀ
  const Distortion d = distortion(*this, f, log_j);
  const Eigen::Matrix3d a = f - g;  // ½ ∂W/∂F
  const double shape = mu_kpa * d.factor;
  // P = shape·A + λ ln J·G, with ∂A_ij/∂F_kl = δ_ik δ_jl + G_il G_kj, ∂G_ij/∂F_kl = −G_il G_kj,
  // ∂shape/∂F_kl = 2γ·shape·A_kl, ∂(ln J)/∂F_kl = G_kl.
  Eigen::Matrix<double, 9, 9> h;
  for (int l = 0; l < 3; ++l) {
    for (int k = 0; k < 3; ++k) {
      for (int jj = 0; jj < 3; ++jj) {
        for (int i = 0; i < 3; ++i) {
          const double swap = g(i, l) * g(k, jj);
          double v = (shape - lambda_kpa * log_j) * swap + lambda_kpa * g(i, jj) * g(k, l) +
                     2.0 * stiffening * shape * a(i, jj) * a(k, l);
          if (i == k && jj == l) v += shape;
          h(i + 3 * jj, k + 3 * l) = v;
        }
      }
    }
  }
  return h;
}

}  // namespace ultrasim::sim
