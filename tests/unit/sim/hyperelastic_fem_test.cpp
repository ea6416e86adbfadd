// HyperelasticFem against references it does not share code with: the exact linear FEM at small
// strain, hand-derived stresses under a large homogeneous compression (the patch test: the
// boundary driven by F₀X, the interior must follow), and the probe contact rules.

#include "ultrasim/sim/hyperelastic_fem.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "block_fixture.hpp"
#include "two_thread_jobs.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace ultrasim::sim {
namespace {

const Material kFat{2, "fat", 20.0, 0.45, 0.0};
const Material kLumen{4, "vein", 1.0, 0.05, 0.0};

testing::Block fat_block(const Eigen::Vector3i& nodes, double stiffening = 0.0) {
  Material m = kFat;
  m.stiffening = stiffening;
  return testing::make_block(nodes, [&](const Eigen::Vector3d&) { return m; });
}

// A soft, compressible lumen 8 mm across at depth 8 under fat, along y.
testing::Block block_with_lumen() {
  return testing::make_block({21, 7, 11}, [](const Eigen::Vector3d& c) {
    return std::hypot(c.x() / 1.6, c.z() - 8.0) < 2.6 ? kLumen : kFat;
  });
}

bool on_boundary(const Eigen::Vector3d& p) {
  return p.x() == -20 || p.x() == 20 || p.y() == -10 || p.y() == 10 || p.z() == 0 || p.z() == 20;
}

TEST(HyperelasticFem, SmallStrainMatchesTheExactLinearFem) {
  const auto b = fat_block({9, 5, 5});
  HyperelasticFem hyper(b.mesh, b.materials, b.fixed);
  ExactFem exact(b.mesh, b.materials, b.fixed);
  std::vector<PrescribedNode> held;
  const auto& p = b.mesh.rest_positions_mm;
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    if (p[n].z() == 0 && std::abs(p[n].x()) <= 5) {
      const Eigen::Vector3d u(1e-5, 0, 1e-4);  // strains ~1e-5: nonlinearity ~1e-5 relative
      held.push_back({n, u});
      hyper.prescribe_displacement(n, u);
    }
  }
  exact.solve(held);
  const auto stats = hyper.solve();
  EXPECT_TRUE(stats.converged);
  const Eigen::VectorXd& want = exact.displacements_mm();
  EXPECT_LT((hyper.displacements_mm() - want).lpNorm<Eigen::Infinity>(),
            1e-4 * want.lpNorm<Eigen::Infinity>());
}

// The boundary held at F₀X: the exact answer is F₀X everywhere, whatever the mesh, and the
// top face (z = 0, outward normal −z, 40 × 20 mm) carries the force −P(F₀)·e_z·A, with
// P₃₃ = μ e^{γW}(s − 1/s) + λ ln s / s for F₀ = diag(1, 1, s) written out by hand here.
TEST(HyperelasticFem, LargeHomogeneousCompressionPassesThePatchTest) {
  for (double stiffening : {0.0, 2.0}) {
    SCOPED_TRACE(stiffening);
    const auto b = fat_block({9, 5, 5}, stiffening);
    const auto& fixed = b.fixed;  // the face z = 20
    const auto& p = b.mesh.rest_positions_mm;
    HyperelasticFem fem(b.mesh, b.materials, fixed);
    const double s = 0.6;  // 40 % compression in depth, about the deepest fixed face
    auto deformed = [&](const Eigen::Vector3d& x) {
      return Eigen::Vector3d(x.x(), x.y(), 20.0 + s * (x.z() - 20.0));
    };
    for (int n = 0; n < b.mesh.node_count(); ++n) {
      if (on_boundary(p[n]) && !fixed[n]) fem.prescribe_displacement(n, deformed(p[n]) - p[n]);
    }
    const auto stats = fem.solve();
    EXPECT_TRUE(stats.converged);
    double worst = 0.0, top_force_z = 0.0;
    for (int n = 0; n < b.mesh.node_count(); ++n) {
      worst = std::max(worst, (fem.deformed_positions_mm()[n] - deformed(p[n])).norm());
      if (p[n].z() == 0.0) top_force_z += fem.reaction_force_mn(n).z();
    }
    EXPECT_LT(worst, 1e-8);
    const double e = kFat.youngs_modulus_kpa, nu = kFat.poisson_ratio;
    const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
    const double w = s * s - 1 - 2 * std::log(s);
    const double p33 = mu * std::exp(stiffening * w) * (s - 1 / s) + lambda * std::log(s) / s;
    EXPECT_NEAR(top_force_z, -p33 * 40.0 * 20.0, 1e-6 * std::abs(p33) * 800.0);
  }
}

ProbeCollider face_at_depth(double depth_mm) {
  return ProbeCollider::linear_face(Eigen::Vector3d(0, 0, depth_mm), Eigen::Quaterniond::Identity(),
                                    30.0, 10.0, 2.0);
}

TEST(HyperelasticFem, APressedLumenClosesWithoutInvertingATet) {
  const auto b = block_with_lumen();
  HyperelasticSettings settings;
  settings.newton_iterations_per_frame = 200;
  HyperelasticFem fem(b.mesh, b.materials, b.fixed, settings);
  double last_force = 0.0;
  for (double depth = 1.0; depth <= 9.0; depth += 1.0) {
    SCOPED_TRACE(depth);
    const auto probe = face_at_depth(depth);
    const auto stats = fem.step(&probe, 0.0);
    ASSERT_TRUE(fem.last_solve_stats().converged);
    EXPECT_FALSE(stats.diverged);
    EXPECT_EQ(stats.inverted_tets, 0);
    EXPECT_GT(stats.contact_force_n, last_force);
    last_force = stats.contact_force_n;
    // No node further inside the probe than the contact tolerance (1 µm).
    for (const auto& x : fem.deformed_positions_mm()) {
      EXPECT_GT(probe.signed_distance_mm(x), -1.5e-3);
    }
    EXPECT_GT(stats.contact_nodes, 0);
  }
  // Lifting the probe lets the tissue go back to rest.
  fem.step(nullptr, 0.0);
  EXPECT_TRUE(fem.last_solve_stats().converged);
  EXPECT_LT(fem.displacements_mm().lpNorm<Eigen::Infinity>(), 1e-6);
}

TEST(HyperelasticFem, StiffeningTissuePushesBackHarderUnderADeepPress) {
  double force[2] = {0.0, 0.0};
  for (int i = 0; i < 2; ++i) {
    const auto b = fat_block({11, 6, 6}, i == 0 ? 0.0 : 3.0);
    HyperelasticFem fem(b.mesh, b.materials, b.fixed);
    for (double depth = 1.0; depth <= 6.0; depth += 1.0) {
      const auto probe = face_at_depth(depth);
      force[i] = fem.step(&probe, 0.0).contact_force_n;
    }
  }
  EXPECT_GT(force[1], 1.2 * force[0]);
}

TEST(HyperelasticFem, ALinearFieldWithInvertedTetsIsTakenBackUntilNoneIs) {
  const auto b = fat_block({9, 5, 5});
  HyperelasticFem fem(b.mesh, b.materials, b.fixed);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
  const auto& p = b.mesh.rest_positions_mm;
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    if (!b.fixed[n]) u[3 * n + 2] = 30.0 * std::exp(-p[n].squaredNorm() / 20.0);  // folds tets
  }
  fem.set_displacements_mm(u);
  EXPECT_EQ(geometry::count_inverted_tets(b.mesh.tets, fem.deformed_positions_mm()), 0);
  EXPECT_GT(fem.displacements_mm().norm(), 0.0);
  EXPECT_THROW(fem.set_displacements_mm(Eigen::VectorXd::Zero(3)), std::invalid_argument);
}

TEST(HyperelasticFem, TwoThreadsGiveTheSameAnswer) {
  const auto b = fat_block({11, 6, 6});
  ultrasim::testing::TwoThreadJobs jobs;
  HyperelasticFem serial(b.mesh, b.materials, b.fixed);
  HyperelasticFem parallel(b.mesh, b.materials, b.fixed, {}, &jobs);
  for (double depth : {1.0, 3.0}) {
    const auto probe = face_at_depth(depth);
    serial.step(&probe, 0.0);
    parallel.step(&probe, 0.0);
  }
  EXPECT_EQ(serial.displacements_mm(), parallel.displacements_mm());
}

TEST(HyperelasticFem, BadInputIsRejectedAtConstruction) {
  auto b = fat_block({5, 3, 3});
  std::vector<std::uint8_t> none(b.fixed.size(), 0);
  EXPECT_THROW(HyperelasticFem(b.mesh, b.materials, none), std::invalid_argument);
  b.materials[0].stiffening = -1.0;
  EXPECT_THROW(HyperelasticFem(b.mesh, b.materials, b.fixed), std::invalid_argument);
  b.materials[0].stiffening = 0.0;
  HyperelasticSettings bad;
  bad.newton_iterations_per_frame = 0;
  EXPECT_THROW(HyperelasticFem(b.mesh, b.materials, b.fixed, bad), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::sim
