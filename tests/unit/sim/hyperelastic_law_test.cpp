// The hyperelastic law against its own definition (finite differences of the energy and the
// stress), against linear elasticity at rest, and against hand-derived closed forms for
// uniaxial compression.

#include "ultrasim/sim/hyperelastic_law.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

namespace ultrasim::sim {
namespace {

const Material kFat{2, "fat", 20.0, 0.45, 0.0};
const Material kStiffening{2, "fat", 20.0, 0.45, 3.0};

Eigen::Matrix3d some_deformation() {
  Eigen::Matrix3d f;
  f << 0.8, 0.15, -0.05,  //
      0.1, 1.1, 0.2,      //
      -0.05, 0.02, 0.7;
  return f;
}

TEST(HyperelasticLaw, StressIsTheDerivativeOfTheEnergy) {
  for (const Material& m : {kFat, kStiffening}) {
    const HyperelasticLaw law = HyperelasticLaw::of(m);
    const Eigen::Matrix3d f = some_deformation();
    const Eigen::Matrix3d p = law.first_piola_kpa(f);
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        Eigen::Matrix3d plus = f, minus = f;
        plus(i, j) += h;
        minus(i, j) -= h;
        const double numeric =
            (law.energy_density_kpa(plus) - law.energy_density_kpa(minus)) / (2 * h);
        EXPECT_NEAR(p(i, j), numeric, 1e-6 * p.norm()) << m.stiffening << " " << i << j;
      }
    }
  }
}

TEST(HyperelasticLaw, TangentIsTheDerivativeOfTheStress) {
  for (const Material& m : {kFat, kStiffening}) {
    const HyperelasticLaw law = HyperelasticLaw::of(m);
    const Eigen::Matrix3d f = some_deformation();
    const Eigen::Matrix<double, 9, 9> tangent = law.stress_derivative_kpa(f);
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) {
        Eigen::Matrix3d plus = f, minus = f;
        plus(k, l) += h;
        minus(k, l) -= h;
        const Eigen::Matrix3d numeric =
            (law.first_piola_kpa(plus) - law.first_piola_kpa(minus)) / (2 * h);
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) {
            EXPECT_NEAR(tangent(i + 3 * j, k + 3 * l), numeric(i, j), 1e-6 * tangent.norm());
          }
        }
      }
    }
    EXPECT_LT((tangent - tangent.transpose()).norm(), 1e-9 * tangent.norm());  // a Hessian
  }
}

TEST(HyperelasticLaw, AtRestItIsLinearElasticity) {
  for (const Material& m : {kFat, kStiffening}) {
    const HyperelasticLaw law = HyperelasticLaw::of(m);
    const Eigen::Matrix3d id = Eigen::Matrix3d::Identity();
    EXPECT_EQ(law.energy_density_kpa(id), 0.0);
    EXPECT_LT(law.first_piola_kpa(id).norm(), 1e-12);
    // Hooke: C_ijkl = λ δij δkl + μ (δik δjl + δil δjk), Lamé constants written out here.
    const double e = m.youngs_modulus_kpa, nu = m.poisson_ratio;
    const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
    const Eigen::Matrix<double, 9, 9> tangent = law.stress_derivative_kpa(id);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        for (int k = 0; k < 3; ++k) {
          for (int l = 0; l < 3; ++l) {
            const double hooke =
                lambda * (i == j) * (k == l) + mu * ((i == k) * (j == l) + (i == l) * (j == k));
            EXPECT_NEAR(tangent(i + 3 * j, k + 3 * l), hooke, 1e-12 * e);
          }
        }
      }
    }
  }
}

TEST(HyperelasticLaw, RotationsCostNothing) {
  const HyperelasticLaw law = HyperelasticLaw::of(kStiffening);
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  EXPECT_NEAR(law.energy_density_kpa(r), 0.0, 1e-12);
  const Eigen::Matrix3d f = some_deformation();
  EXPECT_NEAR(law.energy_density_kpa(r * f), law.energy_density_kpa(f), 1e-12);
  EXPECT_LT((law.first_piola_kpa(r * f) - r * law.first_piola_kpa(f)).norm(), 1e-10);
}

// F = diag(s, 1, 1), by hand from Ψ = μ/(2γ)(e^{γW} − 1) + λ/2 ln²J, W = s² − 1 − 2 ln s:
// P₁₁ = μ e^{γW} (s − 1/s) + λ ln s / s (γ = 0: e^{γW} = 1).
TEST(HyperelasticLaw, UniaxialCompressionMatchesTheClosedForm) {
  for (const Material& m : {kFat, kStiffening}) {
    const HyperelasticLaw law = HyperelasticLaw::of(m);
    for (double s : {0.95, 0.7, 0.4, 0.1}) {
      const double w = s * s - 1 - 2 * std::log(s);
      const double factor = std::exp(m.stiffening * w);
      const double p11 = law.mu_kpa * factor * (s - 1 / s) + law.lambda_kpa * std::log(s) / s;
      const Eigen::Matrix3d p = law.first_piola_kpa(Eigen::Vector3d(s, 1, 1).asDiagonal());
      EXPECT_NEAR(p(0, 0), p11, 1e-12 * std::abs(p11)) << s;
      EXPECT_NEAR(p(1, 1), law.lambda_kpa * std::log(s), 1e-12 * std::abs(p11)) << s;
      EXPECT_NEAR(p(0, 1), 0.0, 1e-12);
    }
  }
}

// Under an isochoric compression F = diag(s, 1/√s, 1/√s) the volume term vanishes and the
// stress grows by exactly e^{γW} over the neo-Hookean's.
TEST(HyperelasticLaw, StiffeningMakesLargeCompressionHarder) {
  const HyperelasticLaw soft = HyperelasticLaw::of(kFat);
  const HyperelasticLaw stiff = HyperelasticLaw::of(kStiffening);
  for (double s : {0.999, 0.8, 0.6}) {
    const Eigen::Matrix3d f = Eigen::Vector3d(s, 1 / std::sqrt(s), 1 / std::sqrt(s)).asDiagonal();
    const double w = s * s + 2 / s - 3;  // I₁ − 3, J = 1
    EXPECT_NEAR(stiff.first_piola_kpa(f)(0, 0) / soft.first_piola_kpa(f)(0, 0),
                std::exp(kStiffening.stiffening * w), 1e-9)
        << s;
  }
}

TEST(HyperelasticLaw, NoEnergyForAnInvertedOrFlatTet) {
  const HyperelasticLaw law = HyperelasticLaw::of(kFat);
  EXPECT_TRUE(std::isinf(law.energy_density_kpa(Eigen::Vector3d(-0.5, 1, 1).asDiagonal())));
  EXPECT_TRUE(std::isinf(law.energy_density_kpa(Eigen::Vector3d(0, 1, 1).asDiagonal())));
  // The volume term grows without bound as a tet flattens: closing lumens cannot pass through.
  EXPECT_GT(law.energy_density_kpa(Eigen::Vector3d(1e-6, 1, 1).asDiagonal()),
            100 * law.energy_density_kpa(Eigen::Vector3d(0.5, 1, 1).asDiagonal()));
}

}  // namespace
}  // namespace ultrasim::sim
