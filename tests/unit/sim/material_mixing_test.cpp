// sim::reuss_average against the closed forms of the uniform-stress (Reuss) mixture.

#include "ultrasim/sim/material_mixing.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

namespace ultrasim::sim {
namespace {

double bulk_kpa(const Material& m) {
  return m.youngs_modulus_kpa / (3.0 * (1.0 - 2.0 * m.poisson_ratio));
}
double shear_kpa(const Material& m) {
  return m.youngs_modulus_kpa / (2.0 * (1.0 + m.poisson_ratio));
}

const Material kMuscle{3, "muscle", 50.0, 0.45, 2.0};
const Material kLumen{4, "vein", 1.0, 0.05, 0.0};

TEST(ReussAverage, OnePhaseComesBackBitForBit) {
  const std::vector<Material> phases{kMuscle, kLumen};
  const Material m = reuss_average(phases, std::vector<double>{3.0, 0.0});
  EXPECT_EQ(m.label, kMuscle.label);
  EXPECT_EQ(m.name, kMuscle.name);
  EXPECT_EQ(m.youngs_modulus_kpa, kMuscle.youngs_modulus_kpa);
  EXPECT_EQ(m.poisson_ratio, kMuscle.poisson_ratio);
  EXPECT_EQ(m.stiffening, kMuscle.stiffening);
}

TEST(ReussAverage, IdenticalPhasesGiveTheSameMaterial) {
  Material twin = kMuscle;
  twin.label = 9;
  const std::vector<Material> phases{kMuscle, twin};
  const Material m = reuss_average(phases, std::vector<double>{0.3, 0.7});
  EXPECT_NEAR(m.youngs_modulus_kpa, kMuscle.youngs_modulus_kpa, 1e-12 * kMuscle.youngs_modulus_kpa);
  EXPECT_NEAR(m.poisson_ratio, kMuscle.poisson_ratio, 1e-14);
}

TEST(ReussAverage, BulkAndShearCompliancesAverageByVolume) {
  // Half muscle, half lumen: 1/K = ½/K₁ + ½/K₂ and 1/G likewise, then E = 9KG/(3K+G).
  const std::vector<Material> phases{kMuscle, kLumen};
  const Material m = reuss_average(phases, std::vector<double>{1.0, 1.0});
  const double k = 1.0 / (0.5 / bulk_kpa(kMuscle) + 0.5 / bulk_kpa(kLumen));
  const double g = 1.0 / (0.5 / shear_kpa(kMuscle) + 0.5 / shear_kpa(kLumen));
  EXPECT_NEAR(bulk_kpa(m), k, 1e-12 * k);
  EXPECT_NEAR(shear_kpa(m), g, 1e-12 * g);
  EXPECT_NEAR(m.stiffening, 1.0, 1e-15);
  // The soft phase governs: under twice its own modulus, far below the muscle's mean with it.
  EXPECT_LT(m.youngs_modulus_kpa, 2.0 * kLumen.youngs_modulus_kpa);
}

TEST(ReussAverage, TakesTheLabelOfTheLargestPhaseAndStaysBetweenThePhases) {
  const std::vector<Material> phases{kMuscle, kLumen};
  for (double f : {0.05, 0.25, 0.5, 0.75, 0.95}) {
    const Material m = reuss_average(phases, std::vector<double>{1.0 - f, f});
    EXPECT_EQ(m.label, f <= 0.5 ? kMuscle.label : kLumen.label) << f;  // a tie: the first
    EXPECT_GT(m.youngs_modulus_kpa, kLumen.youngs_modulus_kpa) << f;
    EXPECT_LT(m.youngs_modulus_kpa, kMuscle.youngs_modulus_kpa) << f;
    EXPECT_GE(m.poisson_ratio, 0.0) << f;
    EXPECT_LT(m.poisson_ratio, 0.5) << f;
  }
}

TEST(ReussAverage, RejectsMismatchedEmptyOrNegativeFractions) {
  const std::vector<Material> phases{kMuscle, kLumen};
  EXPECT_THROW(reuss_average(phases, std::vector<double>{1.0}), std::invalid_argument);
  EXPECT_THROW(reuss_average({}, {}), std::invalid_argument);
  EXPECT_THROW(reuss_average(phases, std::vector<double>{1.0, -0.5}), std::invalid_argument);
  EXPECT_THROW(reuss_average(phases, std::vector<double>{0.0, 0.0}), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::sim
