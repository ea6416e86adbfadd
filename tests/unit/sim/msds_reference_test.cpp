// The explicit MSDS engine (float SIMD spring kernel, msds_spring_lattice.hpp) against a
// deliberately naive reference (tests/support/naive_msds.hpp): one explicit step in double,
// spring by spring. Both start from the same state and take the same steps.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <vector>

#include "block_fixture.hpp"
#include "naive_msds.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim {
namespace {

using testing::Block;
using ultrasim::testing::NaiveMsds;

Block make_block(Eigen::Vector3i nodes = {9, 5, 5}) {
  // Two materials, so that springs on the boundary sum different moduli.
  return testing::make_block(nodes, [](const Eigen::Vector3d& c) {
    return c.z() < 8.0 ? Material{1, "fat", 20.0} : Material{2, "muscle", 50.0};
  });
}

// The same block with its nodes numbered in a random order: its springs lie on no dense
// diagonal, so the engine computes them one by one (the lattice's loose springs). With
// `swapped_pairs`, only that many random pairs of nodes trade numbers: a few loose springs
// among diagonal ones.
Block renumbered(const Block& b, int swapped_pairs = -1) {
  const int n = b.mesh.node_count();
  std::vector<int> new_index(n);
  std::iota(new_index.begin(), new_index.end(), 0);
  std::mt19937 rng(11);
  if (swapped_pairs < 0) {
    std::shuffle(new_index.begin(), new_index.end(), rng);
  } else {
    std::uniform_int_distribution<int> node(0, n - 1);
    for (int i = 0; i < swapped_pairs; ++i) std::swap(new_index[node(rng)], new_index[node(rng)]);
  }
  Block out = b;
  for (int i = 0; i < n; ++i) {
    out.mesh.rest_positions_mm[new_index[i]] = b.mesh.rest_positions_mm[i];
    out.fixed[new_index[i]] = b.fixed[i];
  }
  for (auto& tet : out.mesh.tets) {
    for (auto& node : tet) node = new_index[node];
  }
  return out;
}

MsdsSettings physical_masses() {
  MsdsSettings s;
  s.scale_mass_for_explicit_step = false;
  return s;
}

// Half the explicit bound for this block: a stable step with physical masses.
double half_the_stable_step(const Block& b, const MsdsSettings& s) {
  return 0.5 * MsdsEngine(MsdsIntegrator::kExplicitEuler, b.mesh, b.materials, b.fixed, s)
                   .explicit_stable_time_step_s();
}

Eigen::VectorXd random_displacements(int node_count, double amplitude_mm) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> noise(-amplitude_mm, amplitude_mm);
  Eigen::VectorXd u(3 * node_count);
  for (int i = 0; i < u.size(); ++i) u[i] = noise(rng);
  return u;
}

// Largest difference between the engine's and the reference's nodes, relative to the largest
// reference value of (displacement, velocity).
struct Deviation {
  double position = 0.0;
  double velocity = 0.0;
};

Deviation deviation(const MsdsEngine& engine, const NaiveMsds& r, const Block& b) {
  double dx = 0.0, dv = 0.0, u_max = 0.0, v_max = 0.0;
  for (int i = 0; i < engine.node_count(); ++i) {
    dx = std::max(dx, (engine.deformed_positions_mm()[i] - r.x[i]).norm());
    dv = std::max(dv, (engine.velocities_mm_per_s()[i] - r.v[i]).norm());
    u_max = std::max(u_max, (r.x[i] - b.mesh.rest_positions_mm[i]).norm());
    v_max = std::max(v_max, r.v[i].norm());
  }
  return {u_max > 0.0 ? dx / u_max : dx, v_max > 0.0 ? dv / v_max : dv};
}

// The tolerance. The engine's spring kernel reads positions and velocities rounded to float
// (relative error 2^-24 ≈ 6e-8) and computes and sums each spring's force in float. The largest
// error is the rounding of the positions, ~6e-8 × |x| ≲ 2e-6 mm on these 40 mm blocks, carried
// into a spring's stretch: against the stretches here (0.1–0.3 mm of random or pressed
// displacement) that is ~1e-5 of a spring's force, and the forces on a node cancel only partly,
// so its net force and one step's velocity change are within a few 1e-5. Over the steps compared
// the dynamics are stable and damped (steps at or below the stability bound), so the deviation
// does not grow by more than a small factor. 2e-4 of the largest displacement and velocity: well
// above that rounding, far below any real error (a wrong sign, term or mass shows at O(1)).
constexpr double kTolerance = 2e-4;

void expect_matches_reference(const Block& b, const MsdsSettings& settings, double dt_s, int steps,
                              const ProbeCollider* probe, const Eigen::VectorXd& start_mm,
                              bool reference_uses_engine_masses = false) {
  MsdsEngine engine(MsdsIntegrator::kExplicitEuler, b.mesh, b.materials, b.fixed, settings);
  NaiveMsds reference(b.mesh, b.materials, b.fixed, settings);
  ASSERT_EQ(engine.springs().size(), reference.springs.size());
  if (reference_uses_engine_masses) {
    reference.mass_kg.assign(engine.node_masses_kg().begin(), engine.node_masses_kg().end());
  } else {
    for (int i = 0; i < engine.node_count(); ++i) {
      ASSERT_NEAR(engine.node_masses_kg()[i], reference.mass_kg[i], 1e-12 * reference.mass_kg[i]);
    }
  }
  engine.set_displacements_mm(start_mm);
  for (int i = 0; i < engine.node_count(); ++i) reference.x[i] = engine.deformed_positions_mm()[i];
  Deviation worst;
  for (int s = 0; s < steps; ++s) {
    engine.integrate_unchecked(probe, dt_s, 1);
    reference.step(dt_s, probe);
    const Deviation d = deviation(engine, reference, b);
    ASSERT_TRUE(engine.displacements_mm().allFinite());
    ASSERT_LE(d.position, kTolerance) << "step " << s;
    ASSERT_LE(d.velocity, kTolerance) << "step " << s;
    worst.position = std::max(worst.position, d.position);
    worst.velocity = std::max(worst.velocity, d.velocity);
  }
  if (probe != nullptr) {
    EXPECT_GT(reference.held_nodes, 0) << "the test needs contacts";
  }
  std::printf("MSDS vs naive double reference over %d steps: position %.2e, velocity %.2e\n", steps,
              worst.position, worst.velocity);
}

TEST(MsdsReference, FreeVibrationFromRandomDisplacementsMatchesTheNaiveStep) {
  const Block b = make_block();
  const MsdsSettings s = physical_masses();
  const double dt = half_the_stable_step(b, s);
  expect_matches_reference(b, s, dt, 60, nullptr, random_displacements(b.mesh.node_count(), 0.3));
}

TEST(MsdsReference, PublishedStepWithScaledMassesMatchesTheNaiveStep) {
  // dt 5 ms, masses raised for it (the reference takes the engine's masses: scaling them is
  // MsdsMassScaling's subject, not this test's).
  const Block b = make_block();
  const MsdsSettings s;
  expect_matches_reference(b, s, s.time_step_s, 40, nullptr,
                           random_displacements(b.mesh.node_count(), 0.3), true);
}

// The reference holds the published stick contact; the Coulomb slip has its own tests
// (held_contact_slip_test.cpp, sliding_probe_test.cpp).
MsdsSettings with_stick_contact(MsdsSettings s) {
  s.contact.model = HeldContactModel::kStick;
  return s;
}

TEST(MsdsReference, PressedByAProbeMatchesTheNaiveStepWithItsContacts) {
  const Block b = make_block();
  const MsdsSettings s = with_stick_contact(physical_masses());
  const double dt = half_the_stable_step(b, s);
  // The published sphere, its lowest point 1.5 mm below the skin (z = 0).
  const ProbeCollider probe = ProbeCollider::sphere(
      SphereCollider::behind_face({2.0, 1.0, 1.5}, Eigen::Vector3d::UnitZ(), 15.0));
  expect_matches_reference(b, s, dt, 60, &probe, Eigen::VectorXd::Zero(3 * b.mesh.node_count()));
}

TEST(MsdsReference, ScaledMassesUnderALinearProbeMatchTheNaiveStepWithItsContacts) {
  const Block b = make_block({13, 7, 7});
  const MsdsSettings s = with_stick_contact(MsdsSettings{});
  const ProbeCollider probe =
      ProbeCollider::linear_face({1.0, 0.5, 1.0}, Eigen::Quaterniond::Identity(), 20.0, 8.0, 2.0);
  expect_matches_reference(b, s, s.time_step_s, 40, &probe,
                           Eigen::VectorXd::Zero(3 * b.mesh.node_count()), true);
}

TEST(MsdsReference, AMeshNumberedInRandomOrderMatchesTheNaiveStep) {
  // No dense diagonal: every spring is loose.
  const Block b = renumbered(make_block());
  const MsdsSettings s = physical_masses();
  const double dt = half_the_stable_step(b, s);
  expect_matches_reference(b, s, dt, 60, nullptr, random_displacements(b.mesh.node_count(), 0.3));
}

TEST(MsdsReference, AGridWithAFewNodesRenumberedMatchesTheNaiveStep) {
  // Mostly diagonals, with the springs of the renumbered nodes loose.
  const Block b = renumbered(make_block(), 6);
  const MsdsSettings s = physical_masses();
  const double dt = half_the_stable_step(b, s);
  expect_matches_reference(b, s, dt, 60, nullptr, random_displacements(b.mesh.node_count(), 0.3));
}

}  // namespace
}  // namespace ultrasim::sim
