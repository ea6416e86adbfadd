// ExactFem's probe contact: precomputed Green's functions against solves with the factor,
// frictionless contact against a direct solve with the final contact set eliminated, the parallel
// field update against the serial one, and a probe pushed through the tissue.

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <random>
#include <thread>
#include <vector>

#include "block_fixture.hpp"
#include "direct_solve.hpp"
#include "two_thread_jobs.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace ultrasim::sim {
namespace {

using testing::Block;

Block make_block(Eigen::Vector3i nodes = {11, 7, 6}) {
  return testing::make_block(nodes, [](const Eigen::Vector3d& centroid) {
    return centroid.z() < 8.0 ? Material{1, "fat", 20.0, 0.45} : Material{2, "muscle", 60.0, 0.4};
  });
}

std::vector<std::uint8_t> skin_nodes(const Block& b) {
  std::vector<std::uint8_t> skin(b.mesh.node_count(), 0);
  for (int n = 0; n < b.mesh.node_count(); ++n) skin[n] = b.mesh.rest_positions_mm[n].z() == 0.0;
  return skin;
}

// A linear probe pressing `depth_mm` into the skin at x, beam straight down (+z).
ProbeCollider flat_probe(double x_mm, double depth_mm, double tilt_rad = 0.0) {
  const Eigen::Quaterniond orientation(Eigen::AngleAxisd(tilt_rad, Eigen::Vector3d::UnitY()));
  return ProbeCollider::linear_face(Eigen::Vector3d(x_mm, 0.3, depth_mm), orientation, 24.0, 8.0,
                                    2.0);
}

double relative_max_error(const Eigen::VectorXd& got, const Eigen::VectorXd& want) {
  return (got - want).lpNorm<Eigen::Infinity>() / want.lpNorm<Eigen::Infinity>();
}

TEST(ExactFemContact, PrecomputedSkinGreensFunctionsMatchSolvesWithTheFactor) {
  const Block b = make_block();
  const auto skin = skin_nodes(b);
  ExactFem lazy(b.mesh, b.materials, b.fixed);
  ExactFem precomputed(b.mesh, b.materials, b.fixed, {}, skin);
  EXPECT_EQ(precomputed.contact_candidate_count(), 11 * 7);
  std::vector<int> skin_list;
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (skin[n]) skin_list.push_back(n);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> tilt(-0.4, 0.4), depth(0.2, 1.5);
  for (int frame = 0; frame < 5; ++frame) {
    // Frictionless planes on a random third of the skin, plus one node held on all axes that is
    // not skin (it takes its columns from the factor in both engines).
    std::vector<NormalConstraint> planes;
    std::shuffle(skin_list.begin(), skin_list.end(), rng);
    for (std::size_t i = 0; i < skin_list.size() / 3; ++i) {
      planes.push_back(
          {skin_list[i], Eigen::Vector3d(tilt(rng), tilt(rng), 1.0).normalized(), depth(rng)});
    }
    lazy.solve(planes);
    const auto stats = precomputed.solve(planes);
    EXPECT_EQ(stats.columns_computed, 0) << "frame " << frame;
    EXPECT_EQ(stats.columns_reused, 3 * static_cast<int>(planes.size()));
    // The field is stored in float: exact to float rounding.
    EXPECT_LT(relative_max_error(precomputed.displacements_mm(), lazy.displacements_mm()), 1e-6)
        << "frame " << frame;
    // The capacitance system is double either way; the two factor solves round differently.
    EXPECT_NEAR(stats.contact_force_n, lazy.last_solve_stats().contact_force_n,
                1e-7 * stats.contact_force_n);
  }
  const std::vector<PrescribedNode> mixed = {{skin_list[0], Eigen::Vector3d(0.1, 0.2, 0.9)},
                                             {b.mesh.node_count() / 2, Eigen::Vector3d(0, 0, 0.3)}};
  lazy.solve(mixed);
  const auto stats = precomputed.solve(mixed);
  EXPECT_EQ(stats.columns_computed, 3);  // the interior node only
  EXPECT_LT(relative_max_error(precomputed.displacements_mm(), lazy.displacements_mm()), 1e-6);
}

TEST(ExactFemContact, FrictionlessFlatProbeEqualsDirectSolveWithTheContactDepthsPrescribed) {
  const Block b = make_block();
  ExactFem fem(b.mesh, b.materials, b.fixed, {}, skin_nodes(b));
  const double depth = 1.2;
  // Sized so that every node under the face meets its flat part, none its rounded rim.
  const ProbeCollider probe = ProbeCollider::linear_face(
      Eigen::Vector3d(0.7, 0.3, depth), Eigen::Quaterniond::Identity(), 22.0, 12.0, 1.0);
  const auto stats = fem.step(&probe, 0.0);
  ASSERT_GT(stats.contact_nodes, 4);
  EXPECT_FALSE(stats.diverged);
  // Straight down, a flat face: the contacts are held at depth along z and slide freely in x, y.
  // The field is exact to float rounding: residual forces on free nodes are that small.
  const double rounding_mn = 1e-6 * 1e3 * stats.contact_force_n;
  std::vector<std::pair<int, double>> known;
  std::vector<std::uint8_t> in_contact(b.mesh.node_count(), 0);
  for (int n : fem.constrained_nodes()) {
    in_contact[n] = 1;
    known.emplace_back(3 * n + 2, fem.displacement_mm(n).z());
    EXPECT_NEAR(fem.deformed_positions_mm()[n].z(), depth, 1e-6) << "contact node " << n;
    // Frictionless and pushing: the probe's force on the node points along +z only.
    const Eigen::Vector3d r = fem.reaction_force_mn(n);
    EXPECT_GT(r.z(), 0.0) << "node " << n << " pulled";
    EXPECT_LT(std::hypot(r.x(), r.y()), rounding_mn) << "node " << n << " has friction";
  }
  EXPECT_EQ(static_cast<int>(known.size()), stats.contact_nodes);
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    if (b.fixed[n]) continue;
    // No node ends inside the probe; free nodes are in balance.
    EXPECT_GT(probe.signed_distance_mm(fem.deformed_positions_mm()[n]), -1e-6) << "node " << n;
    if (!in_contact[n]) {
      EXPECT_LT(fem.reaction_force_mn(n).norm(), rounding_mn) << "node " << n;
    }
  }
  const Eigen::VectorXd want = testing::direct_solve_with_known_dofs(
      fem.stiffness(), b.fixed, known, Eigen::VectorXd::Zero(3 * b.mesh.node_count()));
  EXPECT_LT(relative_max_error(fem.displacements_mm(), want), 1e-6);
  // The force the probe exerts equals the support's reaction on the fixed face.
  Eigen::Vector3d support = Eigen::Vector3d::Zero();
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (b.fixed[n]) support += fem.reaction_force_mn(n);
  EXPECT_NEAR(support.norm() / 1e3, stats.contact_force_n, 1e-6 * stats.contact_force_n);
}

TEST(ExactFemContact, TiltedProbeReleasesNodesItWouldPullAndTakesInNodesPushedIntoIt) {
  const Block b = make_block();
  ExactFem fem(b.mesh, b.materials, b.fixed, {}, skin_nodes(b));
  for (int frame = 0; frame < 6; ++frame) {
    const ProbeCollider probe = flat_probe(-5.0 + 2.0 * frame, 0.4 + 0.3 * frame, 0.25);
    const auto stats = fem.step(&probe, 0.0);
    ASSERT_GT(stats.contact_nodes, 0);
    EXPECT_LT(fem.last_solve_stats().contact_rounds, ExactFemSettings{}.max_contact_rounds);
    for (int n = 0; n < b.mesh.node_count(); ++n) {
      if (b.fixed[n]) continue;
      const Eigen::Vector3d p = fem.deformed_positions_mm()[n];
      // On the probe's rounded rim nodes are re-projected to within 10 µm (exact_fem.cpp).
      EXPECT_GT(probe.signed_distance_mm(p), -0.01) << "frame " << frame << " node " << n;
    }
    // Every constraint force pushes out of the probe (along its outward normal there).
    for (int n : fem.constrained_nodes()) {
      const Eigen::Vector3d p = fem.deformed_positions_mm()[n];
      EXPECT_GT(fem.reaction_force_mn(n).dot(probe.closest_surface_point(p).normal), 0.0)
          << "frame " << frame << " node " << n;
    }
  }
}

// Each frame starts from the contacts the last one ended with: a probe held still settles its
// set once and then takes one round a frame. One resting on the skin stays in contact (the image
// depends on it); one hovering 5 µm above it (on its surface, to the 10 µm tolerance) pulls the
// nodes there, lets them go once and leaves them, rather than taking them in and letting them go
// again every other frame.
TEST(ExactFemContact, AStillProbeCarriesItsContactSetOverFrames) {
  const Block b = make_block();
  struct Case {
    double depth_mm, tilt_rad;
    bool in_contact;
  };
  for (const Case c : {Case{1.5, 0.25, true}, Case{0.0, 0.0, true}, Case{-0.005, 0.0, false}}) {
    SCOPED_TRACE(c.depth_mm);
    ExactFem fem(b.mesh, b.materials, b.fixed, {}, skin_nodes(b));
    const ProbeCollider probe = flat_probe(0.0, c.depth_mm, c.tilt_rad);
    std::vector<int> rounds;
    for (int frame = 0; frame < 8; ++frame) {
      const auto stats = fem.step(&probe, 0.0);
      EXPECT_EQ(stats.contact_nodes > 0, c.in_contact) << "frame " << frame;
      rounds.push_back(fem.last_solve_stats().contact_rounds);
    }
    for (int frame = 2; frame < 8; ++frame) EXPECT_EQ(rounds[frame], 1) << "frame " << frame;
    std::printf("depth %.3f mm: rounds %d %d %d %d %d %d %d %d\n", c.depth_mm, rounds[0], rounds[1],
                rounds[2], rounds[3], rounds[4], rounds[5], rounds[6], rounds[7]);
  }
}

TEST(ExactFemContact, ParallelFieldUpdateEqualsSerial) {
  const Block b = make_block();
  ultrasim::testing::TwoThreadJobs jobs;
  ExactFem serial(b.mesh, b.materials, b.fixed, {}, skin_nodes(b));
  ExactFem parallel(b.mesh, b.materials, b.fixed, {}, skin_nodes(b), &jobs);
  for (int frame = 0; frame < 3; ++frame) {
    const ProbeCollider probe = flat_probe(-3.0 + 3.0 * frame, 1.0);
    serial.step(&probe, 0.0);
    parallel.step(&probe, 0.0);
    EXPECT_EQ(serial.displacements_mm(), parallel.displacements_mm()) << "frame " << frame;
  }
}

TEST(ExactFemContact, ProbeThroughTheTissueKeepsTheLastGoodShapeAndSaysSo) {
  const Block b = make_block();
  ExactFem fem(b.mesh, b.materials, b.fixed, {}, skin_nodes(b));
  // A face wider than the block, pressed down a millimetre a frame to below its fixed base (20).
  auto press = [](double depth) {
    return ProbeCollider::linear_face(Eigen::Vector3d(0.0, 0.0, depth),
                                      Eigen::Quaterniond::Identity(), 60.0, 40.0, 2.0);
  };
  Eigen::VectorXd good;
  EngineStepStats stats;
  double depth = 0.0;
  do {
    good = fem.displacements_mm();
    depth += 1.0;
    const ProbeCollider probe = press(depth);
    stats = fem.step(&probe, 0.0);
    ASSERT_TRUE(fem.displacements_mm().allFinite()) << "depth " << depth;
  } while (!stats.diverged && depth < 25.0);
  EXPECT_TRUE(stats.diverged);
  EXPECT_LE(depth, 20.0);  // at the latest when the face reaches the fixed base
  EXPECT_GT(stats.inverted_tets, 0.005 * static_cast<double>(b.mesh.tets.size()));
  EXPECT_EQ(stats.cause, DivergenceCause::kInverted);
  EXPECT_EQ(stats.recovery, Recovery::kKeptLastGood);
  EXPECT_EQ(fem.displacements_mm(), good);
  // Lifting the probe returns the tissue to rest.
  const auto lifted = fem.step(nullptr, 0.0);
  EXPECT_FALSE(lifted.diverged);
  EXPECT_EQ(lifted.contact_nodes, 0);
  EXPECT_LT(fem.displacements_mm().lpNorm<Eigen::Infinity>(), 1e-12);
}

TEST(ExactFemContact, LiveSwitchTakesTheGivenShapeWithFixedNodesAtRest) {
  const Block b = make_block({5, 4, 4});
  ExactFem fem(b.mesh, b.materials, b.fixed);
  Eigen::VectorXd u = Eigen::VectorXd::Constant(3 * b.mesh.node_count(), 0.25);
  fem.set_displacements_mm(u);
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    const double want = b.fixed[n] ? 0.0 : 0.25;
    EXPECT_EQ(fem.displacement_mm(n), Eigen::Vector3d::Constant(want));
    EXPECT_EQ(fem.deformed_positions_mm()[n], b.mesh.rest_positions_mm[n] + fem.displacement_mm(n));
  }
  EXPECT_THROW(fem.set_displacements_mm(Eigen::VectorXd::Zero(5)), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::sim
