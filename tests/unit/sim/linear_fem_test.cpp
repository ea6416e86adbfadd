#include "ultrasim/sim/linear_fem.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <random>

#include "block_fixture.hpp"
#include "engine_settings.hpp"
#include "sliding_reference.hpp"
#include "two_thread_jobs.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/corotational_fem.hpp"

namespace ultrasim::sim {
namespace {

using ultrasim::testing::pcg_settings;

using testing::Block;

// One soft material throughout.
Block make_block(double e_kpa = 30.0, double nu = 0.45, Eigen::Vector3i nodes = {9, 5, 5}) {
  return testing::make_block(nodes, [&](const Eigen::Vector3d&) {
    return Material{1, "tissue", e_kpa, nu};
  });
}

TEST(TetStiffness, IsSymmetricWithSixRigidBodyModes) {
  const Eigen::Vector3d p0(0, 0, 0), p1(2, 0.1, 0), p2(0.3, 1.5, 0.2), p3(0.1, 0.4, 1.8);
  const auto k = tet_stiffness(p0, p1, p2, p3, 50.0, 0.4);
  EXPECT_LT((k - k.transpose()).norm(), 1e-12 * k.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(k);
  int zero_modes = 0;
  for (int i = 0; i < 12; ++i) {
    EXPECT_GT(eig.eigenvalues()[i], -1e-9 * k.norm());
    zero_modes += std::abs(eig.eigenvalues()[i]) < 1e-9 * k.norm();
  }
  EXPECT_EQ(zero_modes, 6);  // three translations, three infinitesimal rotations
}

// Patch test: with a linear displacement field prescribed on the boundary, linear tets reproduce
// it exactly inside, and a uniaxial field's reaction on the top face is E·ε·A (Hooke's law).
TEST(LinearFem, ReproducesUniaxialStrainExactlyAndHookesLaw) {
  const double e_kpa = 30.0, nu = 0.45, strain = -0.02;
  Block b = make_block(e_kpa, nu);
  const auto field = [&](const Eigen::Vector3d& x) {
    // Uniaxial stress along z about the fixed face z = 20: free lateral contraction.
    return Eigen::Vector3d(-nu * strain * x.x(), -nu * strain * x.y(), strain * (x.z() - 20.0));
  };
  const auto& rest = b.mesh.rest_positions_mm;
  // Anchor the one node where the field is zero; every other boundary node is prescribed.
  int anchor = -1;
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (rest[n].isApprox(Eigen::Vector3d(0, 0, 20))) anchor = n;
  ASSERT_GE(anchor, 0);
  std::vector<std::uint8_t> fixed(b.fixed.size(), 0);
  fixed[anchor] = 1;
  LinearFem fem(b.mesh, b.materials, fixed, FemSettings{});
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    const Eigen::Vector3d& x = rest[n];
    const bool boundary = std::abs(std::abs(x.x()) - 20) < 1e-9 ||
                          std::abs(std::abs(x.y()) - 10) < 1e-9 || x.z() == 0.0 || x.z() == 20.0;
    if (boundary && n != anchor) fem.prescribe_displacement(n, field(x));
  }
  const auto stats = fem.solve_to_tolerance(1e-13, 5000);
  EXPECT_LT(stats.relative_residual, 1e-12);
  double top_force_mn = 0.0;
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    EXPECT_LT((fem.displacement_mm(n) - field(rest[n])).norm(), 1e-8) << "node " << n;
    if (rest[n].z() == 0.0) top_force_mn += fem.nodal_force_mn(n).z();
  }
  const double area_mm2 = 40.0 * 20.0;
  // Compressive stress E·ε on the skin face: the load pushes it into the tissue (+z).
  EXPECT_NEAR(top_force_mn, -e_kpa * strain * area_mm2, 1e-6 * e_kpa * area_mm2)
      << "sum of z reactions on the skin face";
}

// With a job system the CG's products run in row bands on two threads: each row is the same sum
// as on one thread, so a press gives the same shape to the last bit.
TEST(LinearFem, AJobSystemGivesTheSerialAnswerExactly) {
  Block b = make_block();
  ultrasim::testing::TwoThreadJobs jobs;
  LinearFem serial(b.mesh, b.materials, b.fixed, FemSettings{});
  LinearFem banded(b.mesh, b.materials, b.fixed, FemSettings{}, &jobs);
  for (double depth : {1.0, 2.0, 3.0}) {
    const auto collider = SphereCollider::behind_face({0, 0, depth}, {0, 0, 1}, 15.0);
    const FemStepStats a = serial.step(collider);
    const FemStepStats c = banded.step(collider);
    EXPECT_EQ(a.pcg_iterations, c.pcg_iterations);
    EXPECT_GT(c.contact_nodes, 0);
  }
  EXPECT_EQ(serial.displacements_mm(), banded.displacements_mm());
}

TEST(LinearFem, RejectsAMeshWithNoFixedNodes) {
  Block b = make_block();
  std::fill(b.fixed.begin(), b.fixed.end(), 0);
  try {
    LinearFem fem(b.mesh, b.materials, b.fixed, FemSettings{});
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("singular"), std::string::npos) << e.what();
  }
}

TEST(LinearFem, RejectsNonPhysicalMaterials) {
  Block b = make_block();
  b.materials[3].poisson_ratio = 0.5;
  EXPECT_THROW(LinearFem(b.mesh, b.materials, b.fixed, FemSettings{}), std::invalid_argument);
  b.materials[3] = Material{1, "nan", std::nan(""), 0.3};
  EXPECT_THROW(LinearFem(b.mesh, b.materials, b.fixed, FemSettings{}), std::invalid_argument);
}

TEST(LinearFem, SphereColliderPushesNodesOutAndForceGrowsWithDepth) {
  Block b = make_block();
  FemSettings settings;
  settings.pcg_iterations_per_frame = 2000;  // converge every frame: this test is about contact
  settings.relative_tolerance = 1e-10;
  LinearFem fem(b.mesh, b.materials, b.fixed, settings);
  double last_force = 0.0;
  for (double depth : {1.0, 2.0, 3.0, 4.0}) {
    const auto collider = SphereCollider::behind_face({0, 0, depth}, {0, 0, 1}, 15.0);
    FemStepStats stats;
    for (int frame = 0; frame < 3; ++frame) stats = fem.step(collider);
    EXPECT_GT(stats.contact_nodes, 0);
    EXPECT_GT(stats.contact_force_n, last_force);
    last_force = stats.contact_force_n;
    for (int n = 0; n < fem.node_count(); ++n) {
      const double dist = (fem.deformed_positions_mm()[n] - collider.center_mm).norm();
      EXPECT_GT(dist, collider.radius_mm - 0.05) << "node " << n << " left inside the probe";
    }
  }
  // The node under the probe centre went down by the indentation depth.
  int top_centre = -1;
  for (int n = 0; n < fem.node_count(); ++n)
    if (b.mesh.rest_positions_mm[n].isApprox(Eigen::Vector3d(0, 0, 0))) top_centre = n;
  ASSERT_GE(top_centre, 0);
  // (Within a micrometre: it slides a little along the sphere, the block's mesh not being
  // symmetric about the probe's axis.)
  EXPECT_NEAR(fem.displacement_mm(top_centre).z(), 4.0, 1e-3);
}

// Coulomb slip solved inside the CG: the held nodes that slide are held along the sphere's normal
// only (each its own) and the converged answer is the frame's equilibrium with them free in their
// tangent planes (against friction where it slides with some), as a fresh factorisation of that
// reduced problem gives it.
TEST(LinearFem, SlidingNodesSettleInTheirTangentPlanesAsTheReducedProblemSays) {
  for (const double mu : {0.0, 0.1}) {
    Block b = make_block(30.0, 0.45, {17, 9, 9});
    FemSettings settings = pcg_settings(20, 1e-13);
    settings.contact = {HeldContactModel::kCoulombSlip, mu};
    LinearFem fem(b.mesh, b.materials, b.fixed, settings);
    // Pressed, then moved 1.5 mm along x: the tissue pulls the held nodes back along the sphere.
    for (int frame = 0; frame < 5; ++frame) {
      fem.step(SphereCollider::behind_face({frame < 3 ? 0.0 : 1.5, 0, 3}, {0, 0, 1}, 15.0));
    }
    int sliding = 0, with_friction = 0, stuck = 0;
    for (int n = 0; n < fem.node_count(); ++n) {
      const auto* hold = fem.sliding_hold(n);
      sliding += hold != nullptr;
      with_friction += hold != nullptr && hold->friction_mn.norm() > 0.0;
      stuck += hold == nullptr && fem.holds_node(n) && !b.fixed[n];
    }
    ASSERT_GT(sliding, 3) << "mu " << mu;
    if (mu == 0.0) {
      EXPECT_EQ(stuck, 0);
      EXPECT_EQ(with_friction, 0);
    } else {
      EXPECT_GT(with_friction, 0);
    }
    const Eigen::VectorXd expected = testing::constrained_equilibrium(fem);
    const FemStepStats solved = fem.solve_to_tolerance(1e-13, 20000);
    EXPECT_LT(solved.relative_residual, 1e-13) << "mu " << mu;
    const double peak = expected.cwiseAbs().maxCoeff();
    ASSERT_GT(peak, 2.0);
    EXPECT_LT((fem.displacements_mm() - expected).cwiseAbs().maxCoeff(), 1e-8 * peak)
        << "mu " << mu;
    // What slid stayed on its tangent plane: the normal component is where the contact put it.
    for (int n = 0; n < fem.node_count(); ++n) {
      const auto* hold = fem.sliding_hold(n);
      if (hold == nullptr) continue;
      EXPECT_NEAR(fem.displacement_mm(n).dot(hold->normal),
                  expected.segment<3>(3 * n).dot(hold->normal), 1e-9);
    }
  }
}

// Friction opposes the slide. One node free, the rest of the block fixed: the probe catches it
// displaced 1 mm sideways and its tissue pulls it back harder than μ × its push, so it slides
// back along the sphere (the radial push-out has no part along the surface), and the friction
// the law gives it points the other way. The corotational FEM solves its slip the same way.
TEST(LinearFem, FrictionOpposesTheSlide) {
  Block b = make_block();
  int node = -1;
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    if (b.mesh.rest_positions_mm[n].isZero()) node = n;
  }
  ASSERT_GE(node, 0);
  std::fill(b.fixed.begin(), b.fixed.end(), 1);
  b.fixed[node] = 0;
  const HeldContactSettings gel{HeldContactModel::kCoulombSlip, 0.3};
  FemSettings fem_settings = pcg_settings(50, 1e-14);
  fem_settings.contact = gel;
  CorotationalSettings corotational_settings;
  corotational_settings.pcg_iterations_per_frame = 50;
  corotational_settings.relative_tolerance = 1e-14;
  corotational_settings.contact = gel;
  LinearFem linear(b.mesh, b.materials, b.fixed, fem_settings);
  CorotationalFem corotational(b.mesh, b.materials, b.fixed, corotational_settings);
  for (DeformationEngine* fem : std::initializer_list<DeformationEngine*>{&linear, &corotational}) {
    Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
    u.segment<3>(3 * node) = Eigen::Vector3d(1.0, 0.0, 0.5);
    fem->set_displacements_mm(u);
    const ProbeCollider probe =
        ProbeCollider::sphere(SphereCollider::behind_face({0, 0, 1.5}, {0, 0, 1}, 15.0));
    fem->step(&probe, 1.0 / 60);
    const auto* hold = fem->sliding_hold(node);
    ASSERT_NE(hold, nullptr) << fem->name() << ": pulled back harder than friction allows";
    ASSERT_GT(hold->friction_mn.norm(), 0.0) << fem->name();
    Eigen::Vector3d slide = fem->displacements_mm().segment<3>(3 * node) - u.segment<3>(3 * node);
    slide -= slide.dot(hold->normal) * hold->normal;
    EXPECT_LT(slide.x(), -0.01) << fem->name() << ": back towards rest";
    EXPECT_LT(hold->friction_mn.dot(slide), 0.0) << fem->name();
    EXPECT_GT(hold->friction_mn.x(), 0.0) << fem->name();
  }
}

// A frictionless probe pushes a node it holds along its normal only: a frame cut short leaves the
// sliding nodes' K u with a part along the face (the CG's unfinished imbalance), which the
// reported force leaves out. A flat face pressed straight down: the force is |Σ (K u)_z|.
TEST(LinearFem, AFrictionlessFaceReportsItsPushAlongItsNormalOnly) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, pcg_settings(2, 1e-12));
  // 9 × 14 mm, 1 mm rim, off the block's middle: it catches the nodes at x = 0 and 5 mm under
  // its flat part, whose imbalances along x do not cancel.
  const ProbeCollider face = ProbeCollider::linear_face(
      Eigen::Vector3d(2.5, 0.0, 1.0), Eigen::Quaterniond::Identity(), 9.0, 14.0, 1.0);
  EngineStepStats stats;
  for (int frame = 0; frame < 3; ++frame) stats = fem.step(&face, 1.0 / 60);
  int sliding = 0;
  Eigen::Vector3d total_mn = Eigen::Vector3d::Zero();
  for (int n = 0; n < fem.node_count(); ++n) {
    if (fem.sliding_hold(n) == nullptr) continue;
    ++sliding;
    EXPECT_TRUE(fem.sliding_hold(n)->normal.isApprox(Eigen::Vector3d::UnitZ()));
    total_mn += fem.nodal_force_mn(n);
  }
  ASSERT_GE(sliding, 3);
  ASSERT_EQ(stats.contact_nodes, sliding);
  EXPECT_GT(std::abs(total_mn.x()), 1e-3 * std::abs(total_mn.z()))
      << "two iterations a frame leave an imbalance along the face";
  EXPECT_NEAR(stats.contact_force_n, std::abs(total_mn.z()) / 1000.0,
              1e-12 * std::abs(total_mn.z()));
}

TEST(LinearFem, WarmStartedFramesConvergeToTheExactAnswer) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, pcg_settings(20, 1e-12));
  const auto collider = SphereCollider::behind_face({0, 0, 3}, {0, 0, 1}, 15.0);
  FemStepStats first = fem.step(collider);
  FemStepStats last = first;
  for (int frame = 0; frame < 200; ++frame) last = fem.step(collider);
  EXPECT_EQ(first.pcg_iterations, 20);
  EXPECT_LT(last.relative_residual, first.relative_residual * 1e-3);
}

TEST(LinearFem, TissueReturnsToRestWhenTheProbeLifts) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, pcg_settings(50, 1e-12));
  const auto collider = SphereCollider::behind_face({0, 0, 4}, {0, 0, 1}, 15.0);
  for (int frame = 0; frame < 30; ++frame) fem.step(collider);
  for (int frame = 0; frame < 200; ++frame) fem.step_without_contact();
  double max_u = 0.0;
  for (int n = 0; n < fem.node_count(); ++n) max_u = std::max(max_u, fem.displacement_mm(n).norm());
  EXPECT_LT(max_u, 1e-6);
}

// A probe lifting slowly must stay in contact while it is still below the skin, even when the
// per-frame iteration budget leaves the tissue lagging: contact ends when holding on would need a
// pull, not when the probe moves a hair away.
TEST(LinearFem, TissueFollowsASlowlyLiftingProbe) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, pcg_settings(20, 1e-12));
  for (int frame = 0; frame <= 60; ++frame)
    fem.step(SphereCollider::behind_face({0, 0, 4.0 * frame / 60}, {0, 0, 1}, 15.0));
  double last_force = 1e9;
  for (int frame = 60; frame >= 6; --frame) {  // lift from 4 mm to 0.4 mm below the skin
    const auto stats =
        fem.step(SphereCollider::behind_face({0, 0, 4.0 * frame / 60}, {0, 0, 1}, 15.0));
    EXPECT_GT(stats.contact_nodes, 0) << "contact lost at depth " << 4.0 * frame / 60;
    // Less each frame, but for a node now and then let go and caught again on this coarse block
    // (the slip moves its neighbours): 5 % once.
    EXPECT_LE(stats.contact_force_n, last_force * 1.1);
    last_force = stats.contact_force_n;
  }
  // Lifted clear of the skin: nothing holds the tissue any more.
  const auto lifted = fem.step(SphereCollider::behind_face({0, 0, -2.0}, {0, 0, 1}, 15.0));
  EXPECT_EQ(lifted.contact_nodes, 0);
}

// Pushed through the 20 mm block, the linear model's answer folds tets: past
// max_inverted_fraction the frame is refused, the last good shape kept, and the stats say why.
TEST(LinearFem, APressThroughTheTissueKeepsTheLastGoodShapeAndSaysTetsInverted) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, pcg_settings(50, 1e-10));
  EngineStepStats stats;
  Eigen::VectorXd good;
  double depth_mm = 0.0;
  do {
    good = fem.displacements_mm();
    depth_mm += 1.0;
    const ProbeCollider probe =
        ProbeCollider::sphere(SphereCollider::behind_face({0, 0, depth_mm}, {0, 0, 1}, 15.0));
    stats = fem.step(&probe, 1.0 / 60);
  } while (!stats.diverged && depth_mm < 30.0);
  ASSERT_TRUE(stats.diverged) << "never refused: the test would mean nothing";
  EXPECT_EQ(stats.cause, DivergenceCause::kInverted);
  EXPECT_EQ(stats.recovery, Recovery::kKeptLastGood);
  EXPECT_EQ(fem.displacements_mm(), good);
}

// A shape handed over folded past the limit (by the corotational FEM, say, switched live) may keep
// its folds while the CG unfolds them, not add to them; refused every frame, it kept them.
TEST(LinearFem, AFoldedShapeHandedOverIsKeptWhileItUnfoldsNotRefused) {
  Block b = make_block();
  FemSettings s = pcg_settings(1, 1e-10);  // one iteration a frame: the folds last a few
  s.max_inverted_fraction = 0.0;           // any fold is over the limit
  LinearFem fem(b.mesh, b.materials, b.fixed, s);
  // The skin's middle pushed through the layers below it (the block is 20 mm deep, 5 mm a layer).
  Eigen::VectorXd folded = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    const Eigen::Vector3d& p = b.mesh.rest_positions_mm[n];
    if (p.z() < 1e-9 && std::abs(p.x()) < 5.1 && std::abs(p.y()) < 5.1) folded[3 * n + 2] = 14.0;
  }
  fem.set_displacements_mm(folded);
  int inverted = geometry::count_inverted_tets(b.mesh.tets, fem.deformed_positions_mm());
  ASSERT_GT(inverted, 0);
  int frames = 0;
  for (int frame = 0; frame < 20 && inverted > 0; ++frame) {
    const EngineStepStats stats = fem.step(nullptr, 1.0 / 60);
    ASSERT_NE(stats.recovery, Recovery::kKeptLastGood) << "frame " << frame;
    ASSERT_LE(stats.inverted_tets, inverted) << "frame " << frame;
    // The start's shape was counted in passing: the frame's own is what is shown.
    for (int n = 0; n < b.mesh.node_count(); ++n) {
      ASSERT_EQ(fem.deformed_positions_mm()[n],
                b.mesh.rest_positions_mm[n] + fem.displacements_mm().segment<3>(3 * n));
    }
    inverted = stats.inverted_tets;
    frames = frame + 1;
  }
  EXPECT_EQ(inverted, 0) << "unfolded";
  EXPECT_GT(frames, 1) << "unfolded at once: the test would mean nothing";
  // A frame that folds more than it started with is still refused, the last good shape kept.
  const Eigen::VectorXd good = fem.displacements_mm();
  const ProbeCollider through =
      ProbeCollider::sphere(SphereCollider::behind_face({0, 0, 25.0}, {0, 0, 1}, 15.0));
  EXPECT_EQ(fem.step(&through, 1.0 / 60).recovery, Recovery::kKeptLastGood);
  EXPECT_EQ(fem.displacements_mm(), good);
}

TEST(LinearFem, StepDoesNotProduceNonFiniteValues) {
  Block b = make_block();
  LinearFem fem(b.mesh, b.materials, b.fixed, FemSettings{});
  for (int frame = 0; frame < 10; ++frame) {
    fem.step(SphereCollider::behind_face({0, 0, 0.5 * frame}, {0, 0, 1}, 15.0));
    for (const auto& p : fem.deformed_positions_mm()) ASSERT_TRUE(p.allFinite());
  }
}

}  // namespace
}  // namespace ultrasim::sim
