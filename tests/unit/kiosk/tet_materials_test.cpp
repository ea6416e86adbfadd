// Per-tet materials from a label volume: the centroid rule, and the Reuss mixture over the
// labels inside a tet, checked against volume fractions found independently (Monte Carlo).

#include "ultrasim/kiosk/tet_materials.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "ultrasim/kiosk/tissue_case.hpp"
#include "ultrasim/sim/material_mixing.hpp"

namespace ultrasim::kiosk {
namespace {

const sim::Material kMuscle{3, "muscle", 50.0, 0.45, 0.0};
const sim::Material kLumen{4, "vein", 1.0, 0.05, 0.0};

// A 10 mm cube, labels at 0.1 mm: lumen above the tilted plane z = 4.3 + 0.2 x, muscle below.
bool in_lumen(const Eigen::Vector3d& p) {
  return p.z() > 4.3 + 0.2 * p.x();
}

imaging::Volume<std::uint8_t> labels() {
  imaging::Volume<std::uint8_t> v({101, 101, 101}, {0.1, 0.1, 0.1}, {0, 0, 0});
  for (int k = 0; k < 101; ++k)
    for (int j = 0; j < 101; ++j)
      for (int i = 0; i < 101; ++i) {
        v.at(i, j, k) = in_lumen(v.index_to_world({double(i), double(j), double(k)})) ? 4 : 3;
      }
  return v;
}

geometry::TetMesh mesh() {
  return geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({0, 0, 0}, {10, 10, 10}, {4, 4, 4}));
}

// The fraction of the tet in the lumen, from uniform random points in it.
double lumen_fraction(const geometry::TetMesh& m, const geometry::Tet& t, std::mt19937& rng) {
  std::exponential_distribution<double> e(1.0);
  int inside = 0;
  constexpr int kPoints = 20000;
  for (int i = 0; i < kPoints; ++i) {
    double w[4], sum = 0;
    for (double& x : w) sum += (x = e(rng));  // uniform on the simplex
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int c = 0; c < 4; ++c) p += w[c] / sum * m.rest_positions_mm[t[c]];
    inside += in_lumen(p);
  }
  return static_cast<double>(inside) / kPoints;
}

TEST(TetMaterials, TetsInOneTissueGetItsMaterialExactlyUnderEitherRule) {
  const auto m = mesh();
  const auto v = labels();
  const std::vector<sim::Material> materials{kMuscle, kLumen};
  const auto reuss = tet_materials(m, v, materials, sim::MaterialMixing::kReuss, "case.toml");
  const auto centroid = tet_materials(m, v, materials, sim::MaterialMixing::kCentroid, "case.toml");
  ASSERT_EQ(reuss.size(), m.tets.size());
  int whole = 0;
  for (int t = 0; t < m.tet_count(); ++t) {
    bool all_in = true, all_out = true;
    for (int n : m.tets[t]) {
      all_in &= in_lumen(m.rest_positions_mm[n]);
      all_out &= !in_lumen(m.rest_positions_mm[n]);
    }
    if (!all_in && !all_out) continue;  // a plane cuts a tet iff it separates its corners
    ++whole;
    const sim::Material& want = all_in ? kLumen : kMuscle;
    EXPECT_EQ(reuss[t].youngs_modulus_kpa, want.youngs_modulus_kpa) << t;
    EXPECT_EQ(reuss[t].poisson_ratio, want.poisson_ratio) << t;
    EXPECT_EQ(centroid[t].label, want.label) << t;
  }
  EXPECT_GT(whole, m.tet_count() / 2);
}

TEST(TetMaterials, CutTetsGetTheReussMixtureOfTheirVolumeFractions) {
  const auto m = mesh();
  const auto v = labels();
  const std::vector<sim::Material> materials{kMuscle, kLumen};
  const auto reuss = tet_materials(m, v, materials, sim::MaterialMixing::kReuss, "case.toml");
  std::mt19937 rng(3);
  int cut = 0;
  for (int t = 0; t < m.tet_count(); ++t) {
    const double f = lumen_fraction(m, m.tets[t], rng);
    if (f < 0.02 || f > 0.98) continue;
    ++cut;
    // The 84-point lattice estimates the fraction to within ~0.1 on tets this size (3.3 mm).
    const auto at = [&](double fraction) {
      return sim::reuss_average(materials, std::vector<double>{1.0 - fraction, fraction})
          .youngs_modulus_kpa;
    };
    const double e = reuss[t].youngs_modulus_kpa;
    EXPECT_LE(e, at(std::max(0.0, f - 0.1)) * (1 + 1e-12)) << "tet " << t << ", fraction " << f;
    EXPECT_GE(e, at(std::min(1.0, f + 0.1)) * (1 - 1e-12)) << "tet " << t << ", fraction " << f;
  }
  EXPECT_GT(cut, 10);
}

TEST(TetMaterials, ALabelWithoutAMaterialIsNamedWithTheSource) {
  const std::vector<sim::Material> only_muscle{kMuscle};
  for (auto mixing : {sim::MaterialMixing::kCentroid, sim::MaterialMixing::kReuss}) {
    try {
      tet_materials(mesh(), labels(), only_muscle, mixing, "cases/x/case.toml");
      ADD_FAILURE() << "expected CaseError";
    } catch (const CaseError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("cases/x/case.toml"), std::string::npos) << what;
      EXPECT_NE(what.find("label 4"), std::string::npos) << what;
    }
  }
}

}  // namespace
}  // namespace ultrasim::kiosk
