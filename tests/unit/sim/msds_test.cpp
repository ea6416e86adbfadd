#include "ultrasim/sim/msds.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <atomic>
#include <cmath>
#include <map>
#include <random>
#include <thread>

#include "block_fixture.hpp"
#include "two_thread_jobs.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::sim {
namespace {

using testing::Block;

constexpr auto kExplicit = MsdsIntegrator::kExplicitEuler;
constexpr auto kImplicit = MsdsIntegrator::kImplicitEuler;

// One soft material throughout (5 mm spacing by default: the block is 40 × 20 × 20 mm).
Block make_block(double e_kpa = 30.0, Eigen::Vector3i nodes = {9, 5, 5}) {
  return testing::make_block(nodes, [&](const Eigen::Vector3d&) {
    return Material{1, "tissue", e_kpa};
  });
}

// The published settings with physical masses: the stability tests study the explicit step's
// true limit, which mass scaling (on by default) moves.
MsdsSettings physical_masses() {
  MsdsSettings s;
  s.scale_mass_for_explicit_step = false;
  return s;
}

MsdsEngine make_engine(const Block& b, MsdsIntegrator integrator,
                       const MsdsSettings& s = physical_masses(), hal::JobSystem* jobs = nullptr) {
  return MsdsEngine(integrator, b.mesh, b.materials, b.fixed, s, jobs);
}

// The published sphere collider, its lowest point `depth_mm` below the skin (z = 0) at x = y = 0.
ProbeCollider press(double depth_mm, double radius_mm = 15.0) {
  return ProbeCollider::sphere(
      SphereCollider::behind_face({0, 0, depth_mm}, Eigen::Vector3d::UnitZ(), radius_mm));
}

MsdsSettings with_step(double dt_s, int steps_per_frame = 20) {
  MsdsSettings s = physical_masses();
  s.time_step_s = dt_s;
  s.steps_per_frame = steps_per_frame;
  return s;
}

double explicit_bound_s(const Block& b) {
  return make_engine(b, kExplicit).explicit_stable_time_step_s();
}

int node_at(const Block& b, const Eigen::Vector3d& p) {
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if ((b.mesh.rest_positions_mm[n] - p).norm() < 1e-9) return n;
  return -1;
}

double mechanical_energy_uj(const MsdsEngine& e) {
  return e.kinetic_energy_uj() + e.elastic_energy_uj();
}

// ---------------------------------------------------------------------------------------------
// The model: springs, masses, validation.

TEST(MsdsModel, HasOneSpringPerUniqueTetEdgeWithTheEdgeAsRestLength) {
  const Block b = make_block();
  std::vector<std::array<std::int32_t, 3>> faces;
  for (const auto& t : b.mesh.tets) {
    faces.push_back({t[0], t[1], t[2]});
    faces.push_back({t[0], t[1], t[3]});
    faces.push_back({t[0], t[2], t[3]});
    faces.push_back({t[1], t[2], t[3]});
  }
  const auto edges = geometry::unique_edges(faces);
  const MsdsEngine engine = make_engine(b, kExplicit);
  ASSERT_EQ(engine.springs().size(), edges.size());
  const auto& p = b.mesh.rest_positions_mm;
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const auto& s = engine.springs()[i];
    EXPECT_EQ(s.a, edges[i][0]);
    EXPECT_EQ(s.b, edges[i][1]);
    EXPECT_DOUBLE_EQ(s.rest_length_mm, (p[s.b] - p[s.a]).norm());
  }
}

TEST(MsdsModel, SumsStiffnessAndDampingOfEveryTetSharingAnEdgeAcrossMaterials) {
  // Soft on the left, four times stiffer on the right: edges in the plane x = 0 are shared by both.
  const Block b = testing::make_block({9, 5, 5}, [](const Eigen::Vector3d& c) {
    return c.x() < 0 ? Material{1, "soft", 10.0} : Material{2, "stiff", 40.0};
  });
  MsdsSettings s;
  s.stiffness_per_modulus_mm = 2.0;
  s.damping_per_stiffness_s = 0.1;
  const MsdsEngine engine = make_engine(b, kExplicit, s);
  std::map<std::pair<int, int>, std::vector<double>> moduli_at_edge;
  for (int t = 0; t < b.mesh.tet_count(); ++t) {
    const auto& tet = b.mesh.tets[t];
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        moduli_at_edge[{std::min(tet[i], tet[j]), std::max(tet[i], tet[j])}].push_back(
            b.materials[t].youngs_modulus_kpa);
  }
  int mixed_edges = 0;
  for (const auto& spring : engine.springs()) {
    const auto& moduli = moduli_at_edge.at({spring.a, spring.b});
    double expected_k = 0.0;
    for (double e : moduli) expected_k += e * s.stiffness_per_modulus_mm;
    EXPECT_NEAR(spring.stiffness_mn_per_mm, expected_k, 1e-12 * expected_k);
    EXPECT_NEAR(spring.damping_mn_s_per_mm, expected_k * s.damping_per_stiffness_s,
                1e-12 * expected_k);
    const auto [lo, hi] = std::minmax_element(moduli.begin(), moduli.end());
    mixed_edges += *lo != *hi;
  }
  EXPECT_GT(mixed_edges, 0) << "the test needs edges shared by tets of different moduli";
}

TEST(MsdsModel, LumpedMassesSumToTotalVolumeTimesDensity) {
  const Block b = make_block();
  MsdsSettings s;
  s.density_kg_per_m3 = 1060.0;
  const MsdsEngine engine = make_engine(b, kImplicit, s);
  double total = 0.0;
  for (double m : engine.node_masses_kg()) {
    EXPECT_GT(m, 0.0);
    total += m;
  }
  const double volume_mm3 = 40.0 * 20.0 * 20.0;
  EXPECT_NEAR(total, volume_mm3 * 1e-9 * 1060.0, 1e-12);
}

TEST(MsdsModel, RejectsAMeshWithNoFixedNodesAsSingular) {
  Block b = make_block();
  std::fill(b.fixed.begin(), b.fixed.end(), 0);
  try {
    make_engine(b, kImplicit);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("singular"), std::string::npos) << e.what();
  }
}

TEST(MsdsModel, RejectsMismatchedOrInvalidMeshInputsWithClearMessages) {
  const auto message_of = [](const Block& b) -> std::string {
    try {
      make_engine(b, kExplicit);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no error";
  };
  Block b = make_block();
  b.materials.pop_back();
  EXPECT_NE(message_of(b).find("one material per tet"), std::string::npos) << message_of(b);
  b = make_block();
  b.fixed.pop_back();
  EXPECT_NE(message_of(b).find("one fixed flag per node"), std::string::npos) << message_of(b);
  b = make_block();
  b.materials[3].youngs_modulus_kpa = -1.0;
  EXPECT_NE(message_of(b).find("youngs_modulus_kpa"), std::string::npos) << message_of(b);
  b = make_block();
  b.materials[3].poisson_ratio = 0.5;
  EXPECT_NE(message_of(b).find("poisson_ratio"), std::string::npos) << message_of(b);
  b = make_block();
  std::swap(b.mesh.tets[7][0], b.mesh.tets[7][1]);  // inside out
  EXPECT_NE(message_of(b).find("tet 7 has no positive volume"), std::string::npos) << message_of(b);
  b = make_block();
  b.mesh.tets[2][3] = b.mesh.node_count();
  EXPECT_NE(message_of(b).find("outside the mesh"), std::string::npos) << message_of(b);
}

TEST(MsdsModel, RejectsSettingsOutOfRange) {
  const Block b = make_block();
  const auto rejects = [&](auto change, const std::string& name) {
    MsdsSettings s;
    change(s);
    try {
      make_engine(b, kImplicit, s);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what()).find(name) != std::string::npos;
    }
    return false;
  };
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.time_step_s = 0.0; }, "time_step_s"));
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.time_step_s = NAN; }, "time_step_s"));
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.steps_per_frame = 0; }, "steps_per_frame"));
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.density_kg_per_m3 = 0.0; }, "density"));
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.damping_per_stiffness_s = -0.1; }, "damping"));
  EXPECT_TRUE(rejects([](MsdsSettings& s) { s.stiffness_per_modulus_mm = 0.0; }, "stiffness"));
}

// ---------------------------------------------------------------------------------------------
// Rest, live switch.

TEST(MsdsRest, HasZeroForceAtRestAndStaysExactlyAtRestWithoutAProbe) {
  const Block b = make_block();
  for (auto integrator : {kExplicit, kImplicit}) {
    MsdsEngine engine = make_engine(b, integrator);
    Eigen::VectorXd forces;
    engine.internal_forces_mn(forces);
    EXPECT_EQ(forces.cwiseAbs().maxCoeff(), 0.0);
    for (int frame = 0; frame < 20; ++frame) {
      const auto stats = engine.step(nullptr, 1.0 / 30);
      ASSERT_FALSE(stats.diverged);
      EXPECT_EQ(stats.contact_nodes, 0);
    }
    EXPECT_EQ(engine.displacements_mm().cwiseAbs().maxCoeff(), 0.0) << engine.name();
    EXPECT_EQ(engine.kinetic_energy_uj(), 0.0);
  }
}

TEST(MsdsLiveSwitch, SetDisplacementsStartsThereAtZeroVelocityWithFixedNodesAtRest) {
  const Block b = make_block();
  MsdsEngine engine = make_engine(b, kImplicit);
  // Leave some velocity behind first, to see that the switch clears it.
  const ProbeCollider probe = press(2.0);
  engine.step(&probe, 0.0);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.3, 0.3);
  Eigen::VectorXd u(3 * b.mesh.node_count());
  for (int i = 0; i < u.size(); ++i) u[i] = noise(rng);
  engine.set_displacements_mm(u);
  const auto& rest = b.mesh.rest_positions_mm;
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    const Eigen::Vector3d want =
        b.fixed[n] ? Eigen::Vector3d::Zero() : Eigen::Vector3d(u.segment<3>(3 * n));
    EXPECT_EQ(Eigen::Vector3d(engine.displacements_mm().segment<3>(3 * n)), want) << n;
    EXPECT_EQ(engine.deformed_positions_mm()[n], rest[n] + want) << n;
    EXPECT_EQ(engine.velocities_mm_per_s()[n], Eigen::Vector3d::Zero()) << n;
  }
  // The state carries over: one frame later the field has relaxed from there, not from rest.
  const Eigen::VectorXd before = engine.displacements_mm();
  const auto stats = engine.step(nullptr, 0.0);
  ASSERT_FALSE(stats.diverged);
  const Eigen::VectorXd& after = engine.displacements_mm();
  EXPECT_GT(after.dot(before) / (after.norm() * before.norm()), 0.5);
  EXPECT_LT(after.norm(), before.norm());

  EXPECT_THROW(engine.set_displacements_mm(Eigen::VectorXd::Zero(5)), std::invalid_argument);
  Eigen::VectorXd bad = Eigen::VectorXd::Zero(u.size());
  bad[4] = NAN;
  EXPECT_THROW(engine.set_displacements_mm(bad), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Stability of the explicit step.

// Largest ω² of M⁻¹K over the free DOFs, from a dense eigensolve of the rest stiffness.
double true_max_omega_squared(const Block& b, const MsdsEngine& engine) {
  std::vector<int> dof_of(b.mesh.node_count(), -1);
  int free_nodes = 0;
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (!b.fixed[n]) dof_of[n] = 3 * free_nodes++;
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(3 * free_nodes, 3 * free_nodes);
  const auto& p = b.mesh.rest_positions_mm;
  for (const auto& s : engine.springs()) {
    const Eigen::Vector3d dir = (p[s.b] - p[s.a]).normalized();
    const Eigen::Matrix3d block = s.stiffness_mn_per_mm * dir * dir.transpose();
    const int a = dof_of[s.a], c = dof_of[s.b];
    if (a >= 0) k.block<3, 3>(a, a) += block;
    if (c >= 0) k.block<3, 3>(c, c) += block;
    if (a >= 0 && c >= 0) {
      k.block<3, 3>(a, c) -= block;
      k.block<3, 3>(c, a) -= block;
    }
  }
  Eigen::VectorXd inv_sqrt_mass(3 * free_nodes);
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (dof_of[n] >= 0)
      inv_sqrt_mass.segment<3>(dof_of[n]).setConstant(1 / std::sqrt(engine.node_masses_kg()[n]));
  const Eigen::MatrixXd scaled = inv_sqrt_mass.asDiagonal() * k * inv_sqrt_mass.asDiagonal();
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(scaled, Eigen::EigenvaluesOnly)
      .eigenvalues()
      .maxCoeff();
}

// Whether forward Euler at dt blows up a small random perturbation within `steps` steps.
bool explicit_euler_grows(const Block& b, double dt_s, int steps) {
  MsdsEngine engine = make_engine(b, kExplicit);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  Eigen::VectorXd u(3 * b.mesh.node_count());
  for (int i = 0; i < u.size(); ++i) u[i] = noise(rng);
  engine.set_displacements_mm(u);
  const double start = mechanical_energy_uj(engine);
  engine.integrate_unchecked(nullptr, dt_s, steps);
  return !(mechanical_energy_uj(engine) < 2.0 * start);
}

TEST(MsdsStability, ExplicitBoundIsSafeAndWithinAFactorTwoOfTheLimitFoundByBisection) {
  const Block b = make_block();
  const MsdsEngine engine = make_engine(b, kExplicit);
  const double bound = engine.explicit_stable_time_step_s();
  ASSERT_GT(bound, 0.0);
  // Bisection on the measured behaviour, in log space, between a stable and an unstable step.
  double stable = 0.5 * bound, unstable = 8.0 * bound;
  ASSERT_FALSE(explicit_euler_grows(b, stable, 400));
  ASSERT_TRUE(explicit_euler_grows(b, unstable, 400));
  for (int i = 0; i < 10; ++i) {  // 16× range to within 0.3 %
    const double mid = std::sqrt(stable * unstable);
    (explicit_euler_grows(b, mid, 400) ? unstable : stable) = mid;
  }
  const double measured = std::sqrt(stable * unstable);
  // The derivation: the measured limit is the forward-Euler limit of the stiffest mode...
  const double predicted = forward_euler_stable_time_step_s(
      true_max_omega_squared(b, engine), engine.settings().damping_per_stiffness_s);
  EXPECT_NEAR(measured, predicted, 0.03 * predicted);
  // ...and the Gershgorin bound is below it, but not by more than a factor 2.
  EXPECT_LE(bound, measured);
  EXPECT_GE(bound, 0.5 * measured);
  RecordProperty("explicit_bound_s", std::to_string(bound));
  RecordProperty("measured_limit_s", std::to_string(measured));
  std::printf("explicit bound %.4g s, measured limit %.4g s (%.3f x bound), predicted %.4g s\n",
              bound, measured, measured / bound, predicted);
}

TEST(MsdsStability, ForwardEulerBoundFormulaCoversBothDampingRegimes) {
  // Underdamped (β ω ≤ 2): dt ≤ β. Overdamped: 4 / (β ω² + ω √(β² ω² − 4)) → 2 / (β ω²).
  EXPECT_DOUBLE_EQ(forward_euler_stable_time_step_s(100.0, 0.1), 0.1);
  EXPECT_DOUBLE_EQ(forward_euler_stable_time_step_s(400.0, 0.1), 0.1);  // β ω = 2: both agree
  EXPECT_NEAR(forward_euler_stable_time_step_s(1e10, 0.1), 2.0 / (0.1 * 1e10), 1e-6 * 2e-9);
  EXPECT_EQ(forward_euler_stable_time_step_s(1e6, 0.0), 0.0);  // undamped: never stable
}

TEST(MsdsStability, ExplicitBelowHalfTheBoundStaysStableFor500StepsUnderAProbe) {
  const Block b = make_block();
  MsdsEngine engine = make_engine(b, kExplicit, with_step(0.5 * explicit_bound_s(b), 20));
  const ProbeCollider probe = press(2.0);
  double first_energy = 0.0;
  for (int frame = 0; frame < 25; ++frame) {
    const auto stats = engine.step(&probe, 1.0 / 30);
    ASSERT_FALSE(stats.diverged) << "frame " << frame;
    ASSERT_EQ(stats.recovery, Recovery::kNone);
    EXPECT_EQ(stats.iterations, 20);
    EXPECT_GT(stats.contact_nodes, 0);
    if (frame == 0) first_energy = mechanical_energy_uj(engine);
  }
  EXPECT_TRUE(engine.displacements_mm().allFinite());
  EXPECT_LT(engine.displacements_mm().cwiseAbs().maxCoeff(), 2.0 + 1e-9);
  // Damped and the probe still: no energy from anywhere after the first frame's push.
  EXPECT_LE(mechanical_energy_uj(engine), first_energy * (1 + 1e-9));
}

TEST(MsdsStability, ExplicitAtTwiceTheBoundBlowsUpWithoutRecoveryAndIsDetectedWithIt) {
  const Block b = make_block();
  const double dt = 2.0 * explicit_bound_s(b);
  const ProbeCollider probe = press(2.0);
  MsdsEngine raw = make_engine(b, kExplicit);
  raw.integrate_unchecked(&probe, dt, 1);
  const double after_push = mechanical_energy_uj(raw);
  raw.integrate_unchecked(&probe, dt, 200);
  EXPECT_FALSE(mechanical_energy_uj(raw) < 1e6 * after_push) << "no growth at 2x the bound";

  MsdsEngine checked = make_engine(b, kExplicit, with_step(dt, 20));
  bool detected = false;
  for (int frame = 0; frame < 10 && !detected; ++frame) {
    const auto stats = checked.step(&probe, 1.0 / 30);
    detected = stats.diverged;
    EXPECT_TRUE(checked.displacements_mm().allFinite());
  }
  EXPECT_TRUE(detected);
}

TEST(MsdsStability, ImplicitStaysStableAtAHundredTimesTheExplicitBoundAndAtThePublishedStep) {
  const Block b = make_block();
  for (double dt : {100.0 * explicit_bound_s(b), MsdsSettings{}.time_step_s}) {
    MsdsEngine engine = make_engine(b, kImplicit, with_step(dt, 20));
    double previous_energy = std::numeric_limits<double>::infinity();
    for (int frame = 0; frame < 10; ++frame) {
      const ProbeCollider probe = press(3.0);
      const auto stats = engine.step(&probe, 1.0 / 30);
      ASSERT_FALSE(stats.diverged) << "dt " << dt << " frame " << frame;
      EXPECT_GT(stats.contact_nodes, 0);
      // The probe is still: backward Euler only dissipates after its first push.
      const double energy = mechanical_energy_uj(engine);
      EXPECT_LE(energy, previous_energy * (1 + 1e-9)) << "dt " << dt << " frame " << frame;
      previous_energy = energy;
    }
    EXPECT_TRUE(engine.displacements_mm().allFinite());
    EXPECT_LT(engine.displacements_mm().cwiseAbs().maxCoeff(), 3.0 + 1e-9);
  }
}

// ---------------------------------------------------------------------------------------------
// Recovery.

TEST(MsdsRecovery, PublishedStepFarPastTheBoundIsDetectedAndResetToRest) {
  const Block b = make_block();
  MsdsEngine engine = make_engine(b, kExplicit);  // published dt: orders past the bound
  ASSERT_GT(engine.settings().time_step_s, 1000 * engine.explicit_stable_time_step_s());
  const ProbeCollider probe = press(2.0);
  const auto stats = engine.step(&probe, 1.0 / 30);
  EXPECT_TRUE(stats.diverged);
  EXPECT_TRUE(stats.cause == DivergenceCause::kEnergy || stats.cause == DivergenceCause::kNonFinite)
      << cause_key(stats.cause);
  EXPECT_EQ(stats.recovery, Recovery::kReset);
  EXPECT_TRUE(engine.displacements_mm().allFinite());
  EXPECT_EQ(engine.displacements_mm().cwiseAbs().maxCoeff(), 0.0);
  for (const auto& x : engine.deformed_positions_mm()) EXPECT_TRUE(x.allFinite());
  EXPECT_EQ(stats.contact_nodes, 0);
  // Lifted off, it stays at rest.
  const auto lifted = engine.step(nullptr, 1.0 / 30);
  EXPECT_FALSE(lifted.diverged);
  EXPECT_EQ(engine.displacements_mm().cwiseAbs().maxCoeff(), 0.0);
}

TEST(MsdsRecovery, ModeratelyUnstableStepIsDetectedWithinAFewFramesAndRecoveredBySubstepping) {
  const Block b = make_block();
  // Past the true limit (the bound is ~0.7 of it), but half of it is below the bound.
  MsdsEngine engine = make_engine(b, kExplicit, with_step(2.0 * explicit_bound_s(b), 20));
  const ProbeCollider probe = press(2.0);
  // Overdamped, the unstable mode is nearly all velocity (positions move by v·dt): its kinetic
  // energy grows ~3× a step and reaches the ceiling within a few frames.
  EngineStepStats stats;
  int frame = 0;
  for (; frame < 5 && !stats.diverged; ++frame) {
    stats = engine.step(&probe, 1.0 / 30);
    EXPECT_TRUE(engine.displacements_mm().allFinite());
    EXPECT_LT(engine.displacements_mm().cwiseAbs().maxCoeff(), 2.5) << "frame " << frame;
  }
  ASSERT_TRUE(stats.diverged);
  EXPECT_EQ(stats.recovery, Recovery::kSubstepped);
  EXPECT_GT(stats.iterations, 20);  // the accepted run took more, smaller steps
  EXPECT_EQ(engine.inverted_tet_count(), 0);
  EXPECT_GT(stats.contact_nodes, 0);
  EXPECT_LT(engine.kinetic_energy_uj(), 1e-6 * engine.kinetic_energy_ceiling_uj());
  EXPECT_GT(engine.displacements_mm().cwiseAbs().maxCoeff(), 1.0);  // the press is shown
}

TEST(MsdsRecovery, ANodeRunningAwayAloneIsCaughtThoughTheWholeLatticesCeilingIsFarOff) {
  // A node pulled twice its springs' length sideways: so stretched, they stiffen sideways past
  // what the masses were scaled for (the rest lattice's bound), and the node alone oscillates
  // with a growing swing. One node's energy is far below the ceiling of the lattice's 9,000
  // springs and fewer tets invert than a frame may keep (a probe's rim folds a few), so only the
  // node's own ceiling notices.
  const Block b = make_block(30.0, {17, 9, 9});  // 2.5 mm spacing
  const int node = node_at(b, {10, 0, 10});
  Eigen::VectorXd pulled = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
  pulled.segment<3>(3 * node) = Eigen::Vector3d(5.0, 1.5, 0.0);
  const MsdsSettings published;  // dt 5 ms, 20 steps, masses scaled
  const auto fastest_mm_per_s = [](const MsdsEngine& e) {
    double fastest = 0.0;
    for (const auto& v : e.velocities_mm_per_s()) fastest = std::max(fastest, v.norm());
    return fastest;
  };
  MsdsEngine raw = make_engine(b, kExplicit, published);
  raw.set_displacements_mm(pulled);
  raw.integrate_unchecked(nullptr, published.time_step_s, published.steps_per_frame);
  ASSERT_GT(fastest_mm_per_s(raw), 100.0) << "the test needs a node running away";
  ASSERT_LT(raw.kinetic_energy_uj(), 1e-2 * raw.kinetic_energy_ceiling_uj());
  ASSERT_LE(raw.inverted_tet_count(),
            published.max_inverted_fraction * static_cast<double>(b.mesh.tets.size()));

  MsdsEngine engine = make_engine(b, kExplicit, published);
  engine.set_displacements_mm(pulled);
  const auto first = engine.step(nullptr, 1.0 / 60);
  EXPECT_TRUE(first.diverged);
  EXPECT_EQ(first.cause, DivergenceCause::kRunaway);
  EXPECT_EQ(first.recovery, Recovery::kSubstepped);  // half the step holds the stretched springs
  // It relaxes as an overdamped lattice does, no faster than the strain it started with drives it
  // (5.2 mm / β ≈ 52 mm/s), and on towards rest (the node, heavier since, swings a little).
  double previous_mm = pulled.norm();
  for (int frame = 1; frame < 10; ++frame) {
    EXPECT_LT(fastest_mm_per_s(engine), 52.0) << "frame " << frame;
    const double largest_mm = engine.displacements_mm().cwiseAbs().maxCoeff();
    EXPECT_LT(largest_mm, 1.05 * previous_mm) << "frame " << frame;
    previous_mm = largest_mm;
    engine.step(nullptr, 1.0 / 60);
  }
  EXPECT_LT(previous_mm, 0.1);

  // With no time for smaller steps (each frame cut short after its first check, 4 steps) the
  // frame that catches it keeps its start, where the node is still pulled long: pulled half as
  // far again, it ran away from there within the 4 steps in each of the 40 frames. Its mass is
  // now scaled for its stretched springs, so the frames after relax it instead.
  MsdsEngine starved = make_engine(b, kExplicit, published);
  const Eigen::VectorXd further = 1.5 * pulled;
  starved.set_displacements_mm(further);
  const double mass_scale_before = starved.mass_scale();
  const StepBudget no_time = [] { return false; };
  int refused = 0;
  for (int frame = 0; frame < 40; ++frame) {
    const auto stats = starved.step_within(nullptr, 1.0 / 60, no_time);
    EXPECT_TRUE(stats.cut_short) << "frame " << frame;
    refused += stats.recovery == Recovery::kKeptLastGood;
    EXPECT_LT(fastest_mm_per_s(starved), 150.0) << "frame " << frame;
  }
  EXPECT_EQ(refused, 1);
  EXPECT_GT(starved.mass_scale(), mass_scale_before);
  EXPECT_LT(starved.displacements_mm().cwiseAbs().maxCoeff(), 0.5);
}

TEST(MsdsMassScaling, PublishedStepIsStableWithScaledMassesAndSettlesWhereImplicitDoes) {
  const Block b = make_block();
  MsdsSettings published;  // dt 5 ms, 20 steps, masses scaled (the defaults)
  MsdsEngine scaled = make_engine(b, kExplicit, published);
  EXPECT_GT(scaled.mass_scale(), 100.0);  // the physical bound is orders below 5 ms
  EXPECT_GE(scaled.explicit_stable_time_step_s(), published.time_step_s);
  MsdsEngine implicit = make_engine(b, kImplicit, published);
  const ProbeCollider probe = press(2.0);
  EngineStepStats explicit_stats, implicit_stats;
  for (int frame = 0; frame < 120; ++frame) {
    explicit_stats = scaled.step(&probe, 1.0 / 60);
    ASSERT_FALSE(explicit_stats.diverged) << "frame " << frame;
    implicit_stats = implicit.step(&probe, 1.0 / 60);
  }
  // Mass changes the motion, not the statics: both settle under the probe with the same force
  // (the contact set each ends with depends on its path of steps, so shapes differ a little).
  EXPECT_LT(scaled.kinetic_energy_uj(), 1e-6 * scaled.kinetic_energy_ceiling_uj());
  EXPECT_NEAR(explicit_stats.contact_force_n, implicit_stats.contact_force_n,
              0.1 * implicit_stats.contact_force_n);
  EXPECT_NEAR(scaled.displacements_mm().lpNorm<Eigen::Infinity>(),
              implicit.displacements_mm().lpNorm<Eigen::Infinity>(), 0.05);
}

TEST(MsdsRecovery, ProbeDeeperThanTheTissueReportsInvertedTetsAndNeverNaN) {
  const Block b = make_block();
  const ProbeCollider through = press(25.0);  // the tissue is 20 mm deep
  for (auto integrator : {kImplicit, kExplicit}) {
    const MsdsSettings s =
        integrator == kImplicit ? MsdsSettings{} : with_step(0.5 * explicit_bound_s(b), 20);
    MsdsEngine engine = make_engine(b, integrator, s);
    for (int frame = 0; frame < 3; ++frame) {
      const auto stats = engine.step(&through, 1.0 / 30);
      EXPECT_TRUE(stats.diverged) << engine.name();
      EXPECT_EQ(stats.cause, DivergenceCause::kInverted) << engine.name();
      EXPECT_GT(stats.inverted_tets, 0) << engine.name();
      // Smaller steps cannot unfold them: the last good shape (rest, here) is kept.
      EXPECT_EQ(stats.recovery, Recovery::kKeptLastGood) << engine.name();
      EXPECT_TRUE(engine.displacements_mm().allFinite()) << engine.name();
      EXPECT_EQ(engine.inverted_tet_count(), 0) << engine.name();
    }
  }
}

// A shape handed over folded past the limit (the corotational FEM keeps tets pressed flat under a
// probe; switched live, the MSDS gets them) may keep its folds while the frames unfold it, not
// add to them. Refused every frame instead, it kept them until the method changed (the large
// soak: the implicit MSDS refused 274 frames in a row).
TEST(MsdsRecovery, AFoldedShapeHandedOverIsKeptWhileItUnfoldsNotRefused) {
  const Block b = make_block();
  const int skin_centre = node_at(b, {0, 0, 0});
  ASSERT_GE(skin_centre, 0);
  Eigen::VectorXd folded = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
  folded[3 * skin_centre + 2] = 14.0;  // through the two nodes below it
  for (auto integrator : {kImplicit, kExplicit}) {
    MsdsSettings s;                 // the kiosk's (the explicit one's masses scaled for its step)
    s.max_inverted_fraction = 0.0;  // any fold is over the limit
    MsdsEngine engine = make_engine(b, integrator, s);
    engine.set_displacements_mm(folded);
    int inverted = engine.inverted_tet_count();
    ASSERT_GT(inverted, 0);
    int frame = 0;
    for (; frame < 200 && inverted > 0; ++frame) {
      const EngineStepStats stats = engine.step(nullptr, 1.0 / 30);
      ASSERT_NE(stats.recovery, Recovery::kKeptLastGood) << engine.name() << " frame " << frame;
      ASSERT_LE(engine.inverted_tet_count(), inverted) << engine.name() << " frame " << frame;
      EXPECT_EQ(stats.inverted_tets, engine.inverted_tet_count()) << engine.name();
      inverted = engine.inverted_tet_count();
    }
    EXPECT_EQ(inverted, 0) << engine.name() << ": unfolded";
    std::printf("%s: unfolded in %d frames\n", engine.name().data(), frame);
    // A frame that folds more than it started with is still refused.
    const ProbeCollider through = press(25.0);
    EXPECT_EQ(engine.step(&through, 1.0 / 30).recovery, Recovery::kKeptLastGood) << engine.name();
  }
}

// Untouched by the probe, a relaxing lattice that folds a tet more than it started with is not
// refused: keeping the start (as folded) would only stop it relaxing (the default case's
// implicit MSDS refused its relaxation for 450 frames, ~200 tets folded, its limit). A node
// inside the block pulled 15 mm sideways: 10 tets folded at the start, 11 on the way back.
TEST(MsdsRecovery, AnUntouchedLatticeRelaxesThroughFoldsUnrefused) {
  const Block b = make_block();
  const int inside = node_at(b, {0, 0, 5});
  ASSERT_GE(inside, 0);
  Eigen::VectorXd pulled = Eigen::VectorXd::Zero(3 * b.mesh.node_count());
  pulled[3 * inside + 0] = pulled[3 * inside + 1] = 15.0;
  for (auto integrator : {kImplicit, kExplicit}) {
    MsdsSettings s;
    s.max_inverted_fraction = 0.0;  // any fold is over the limit
    MsdsEngine engine = make_engine(b, integrator, s);
    engine.set_displacements_mm(pulled);
    const int start = engine.inverted_tet_count();
    int most = start;
    for (int frame = 0; frame < 40; ++frame) {
      const EngineStepStats stats = engine.step(nullptr, 1.0 / 30);
      ASSERT_FALSE(stats.diverged) << engine.name() << " frame " << frame;
      most = std::max(most, engine.inverted_tet_count());
    }
    EXPECT_GT(most, start) << engine.name() << ": never folded more than at the start";
    EXPECT_EQ(engine.inverted_tet_count(), 0) << engine.name();
  }
}

// ---------------------------------------------------------------------------------------------
// A press, and the job system.

TEST(MsdsPress, ImplicitPressSettlesToAStaticStateShapedLikeTheQuasiStaticFem) {
  const Block b = make_block(30.0, {9, 5, 9});
  const double depth = 3.0, radius = 15.0;
  const ProbeCollider probe = press(depth, radius);
  // Implicit Euler is stable at any step: a few long steps per frame settle quickly. Without
  // friction, so the linear FEM below holds the same contact law; the held nodes' slide along the
  // sphere settles over tens of frames (kinetic energy down ×8 every 20).
  MsdsSettings frictionless = with_step(0.025, 4);
  frictionless.contact.friction_coefficient = 0.0;
  MsdsEngine engine = make_engine(b, kImplicit, frictionless);
  EngineStepStats stats;
  for (int frame = 0; frame < 140; ++frame) {
    stats = engine.step(&probe, 1.0 / 30);
    ASSERT_FALSE(stats.diverged) << "frame " << frame;
  }
  ASSERT_GT(stats.contact_nodes, 0);
  EXPECT_GT(stats.contact_force_n, 0.0);
  const Eigen::VectorXd& u = engine.displacements_mm();
  // The node under the probe's lowest point is pressed in by the press depth (to a micrometre: it
  // slides a little along the sphere, the lattice not being symmetric about its axis).
  const int top = node_at(b, {0, 0, 0});
  ASSERT_GE(top, 0);
  EXPECT_NEAR(u[3 * top + 2], depth, 1e-3);
  // Below it, the push decays with depth.
  double above = u[3 * top + 2];
  for (double z : {5.0, 10.0, 15.0}) {
    const int n = node_at(b, {0, 0, z});
    ASSERT_GE(n, 0);
    EXPECT_GT(u[3 * n + 2], 0.0) << "z " << z;
    EXPECT_LT(u[3 * n + 2], above) << "z " << z;
    above = u[3 * n + 2];
  }
  // Static: the springs balance at every free node the probe does not hold, to a tiny fraction
  // of the force the probe exerts.
  Eigen::VectorXd forces;
  engine.internal_forces_mn(forces);
  std::vector<std::uint8_t> held(b.mesh.node_count(), 0);
  std::vector<NodeContact> contacts;
  find_contacts(probe, engine.deformed_positions_mm(), b.fixed, 1e-6, contacts);
  for (const auto& c : contacts) held[c.node] = 1;
  double worst_free = 0.0;
  for (int n = 0; n < b.mesh.node_count(); ++n)
    if (!b.fixed[n] && !held[n]) worst_free = std::max(worst_free, forces.segment<3>(3 * n).norm());
  EXPECT_LT(worst_free, 1e-6 * 1000.0 * stats.contact_force_n);
  EXPECT_LT(engine.kinetic_energy_uj(), 1e-12 * engine.elastic_energy_uj());

  // A different model from linear FEM, but the same press must move the tissue the same way.
  FemSettings frictionless_fem;
  frictionless_fem.contact.friction_coefficient = 0.0;
  LinearFem fem(b.mesh, b.materials, b.fixed, frictionless_fem);
  for (int frame = 0; frame < 100; ++frame) {  // its slip settles a step a frame
    fem.step(SphereCollider::behind_face({0, 0, depth}, Eigen::Vector3d::UnitZ(), radius));
    fem.solve_to_tolerance(1e-10, 5000);
  }
  Eigen::VectorXd u_fem(u.size());
  for (int n = 0; n < b.mesh.node_count(); ++n) u_fem.segment<3>(3 * n) = fem.displacement_mm(n);
  // The springs' lattice is less incompressible than ν = 0.45, so the sideways bulge differs
  // more than the push along the beam.
  Eigen::VectorXd uz(u.size() / 3), uz_fem(u.size() / 3);
  for (int n = 0; n < b.mesh.node_count(); ++n) {
    uz[n] = u[3 * n + 2];
    uz_fem[n] = u_fem[3 * n + 2];
  }
  const double cosine = u.dot(u_fem) / (u.norm() * u_fem.norm());
  const double cosine_z = uz.dot(uz_fem) / (uz.norm() * uz_fem.norm());
  EXPECT_GT(cosine, 0.8);
  EXPECT_GT(cosine_z, 0.9);
  std::printf("MSDS vs linear FEM press: cosine %.4f (z only %.4f), |u| ratio %.3f, force %.4g N\n",
              cosine, cosine_z, u.norm() / u_fem.norm(), stats.contact_force_n);
}

TEST(MsdsPress, AProbeJumpThatFoldsTetsForOneStepIsNotADivergence) {
  // From rest straight to 4 mm: the skin nodes land below the next layer (2.5 mm) for the first
  // step, and the springs unfold them in the next.
  const Block b = make_block(30.0, {9, 5, 9});
  MsdsEngine engine = make_engine(b, kImplicit);
  const ProbeCollider probe = press(4.0);
  MsdsEngine probe_only = make_engine(b, kImplicit);
  probe_only.integrate_unchecked(&probe, engine.settings().time_step_s, 1);
  ASSERT_GT(probe_only.inverted_tet_count(), 0) << "the test needs a fold after the first step";
  const auto stats = engine.step(&probe, 1.0 / 30);
  EXPECT_FALSE(stats.diverged);
  // Held in all three axes (the published stick), the springs unfold them within the frame.
  // Held by Coulomb's law, the skin nodes also slide outwards along the sphere as they unfold,
  // both layers caught on it: up to 3 tets stay folded over the next frames, within the limit
  // (each frame reports them), and the last tet squeezed flat between them (its volume's sign
  // decided by rounding: the vectorised count calls it positive, the plain one zero) opens by
  // the eleventh.
  const double limit = engine.settings().max_inverted_fraction * b.mesh.tet_count();
  int frames = 1;
  for (; frames < 12 && engine.inverted_tet_count() > 0; ++frames) {
    const auto next = engine.step(&probe, 1.0 / 30);
    EXPECT_FALSE(next.diverged);
    EXPECT_LE(next.inverted_tets, limit);
  }
  EXPECT_EQ(engine.inverted_tet_count(), 0);
  MsdsSettings stick_settings = physical_masses();
  stick_settings.contact.model = HeldContactModel::kStick;
  MsdsEngine stick = make_engine(b, kImplicit, stick_settings);
  const auto stick_stats = stick.step(&probe, 1.0 / 30);
  EXPECT_FALSE(stick_stats.diverged);
  EXPECT_EQ(stick_stats.inverted_tets, 0);
  EXPECT_EQ(stick.inverted_tet_count(), 0);
}

TEST(MsdsPress, LiftingTheProbeLetsTheTissueRelaxBackToRest) {
  const Block b = make_block();
  MsdsEngine engine = make_engine(b, kImplicit, with_step(0.025, 4));
  const ProbeCollider probe = press(2.0);
  for (int frame = 0; frame < 10; ++frame) engine.step(&probe, 1.0 / 30);
  ASSERT_GT(engine.displacements_mm().cwiseAbs().maxCoeff(), 1.9);
  for (int frame = 0; frame < 40; ++frame) {
    const auto stats = engine.step(nullptr, 1.0 / 30);
    ASSERT_FALSE(stats.diverged);
    EXPECT_EQ(stats.contact_nodes, 0);
    EXPECT_EQ(stats.contact_force_n, 0.0);
  }
  EXPECT_LT(engine.displacements_mm().cwiseAbs().maxCoeff(), 1e-4);
}

// The Coulomb slip moves only nodes the probe can reach (the skin): with none reachable, every
// caught node is held where it was caught, as the published stick contact holds it, to the bit.
TEST(MsdsPress, NodesTheProbeCannotReachAreHeldAsTheStickContactHoldsThem) {
  const Block b = make_block();
  const ProbeCollider probe = ProbeCollider::sphere(
      SphereCollider::behind_face({1.3, 0.7, 2.0}, Eigen::Vector3d(0.3, 0, 1).normalized(), 15.0));
  const std::vector<std::uint8_t> none(b.mesh.node_count(), 0);
  for (auto integrator : {kExplicit, kImplicit}) {
    const MsdsSettings s =
        integrator == kImplicit ? with_step(0.025, 4) : with_step(0.5 * explicit_bound_s(b), 20);
    MsdsSettings stick_s = s;
    stick_s.contact.model = HeldContactModel::kStick;
    MsdsEngine unreachable(integrator, b.mesh, b.materials, b.fixed, s, nullptr, none);
    MsdsEngine stick = make_engine(b, integrator, stick_s);
    MsdsEngine slip = make_engine(b, integrator, s);
    for (int frame = 0; frame < 5; ++frame) {
      unreachable.step(&probe, 1.0 / 30);
      stick.step(&probe, 1.0 / 30);
      slip.step(&probe, 1.0 / 30);
    }
    EXPECT_EQ(unreachable.displacements_mm(), stick.displacements_mm());
    EXPECT_NE(slip.displacements_mm(), stick.displacements_mm()) << "the tilted press slides";
  }
  const std::vector<std::uint8_t> too_few(3, 1);
  EXPECT_THROW(
      MsdsEngine(kImplicit, b.mesh, b.materials, b.fixed, MsdsSettings{}, nullptr, too_few),
      std::invalid_argument);
}

TEST(MsdsPress, ContactForceGrowsWithPressDepth) {
  const Block b = make_block();
  double previous = 0.0;
  for (double depth : {1.0, 2.0, 3.0}) {
    MsdsEngine engine = make_engine(b, kImplicit, with_step(0.025, 4));
    const ProbeCollider probe = press(depth);
    EngineStepStats stats;
    for (int frame = 0; frame < 12; ++frame) stats = engine.step(&probe, 1.0 / 30);
    EXPECT_GT(stats.contact_force_n, previous) << "depth " << depth;
    previous = stats.contact_force_n;
  }
}

// A stitched frame with no time for all its seam exchanges covers its time in fewer parts: a
// frame stretched twofold is, to the bit, a frame of twice the simulated time (the implicit
// integrator's steps twice as long, the explicit one's twice as many), and only the next frame
// is stretched.
TEST(MsdsFrame, AStretchedFrameIsAFrameOfThatManyTimesTheSimulatedTime) {
  const Block b = make_block();
  for (auto integrator : {kExplicit, kImplicit}) {
    const MsdsSettings s =
        integrator == kImplicit ? with_step(0.025, 4) : with_step(0.5 * explicit_bound_s(b), 10);
    MsdsSettings twice = s;
    twice.steps_per_frame *= 2;
    MsdsEngine stretched = make_engine(b, integrator, s);
    MsdsEngine long_frames = make_engine(b, integrator, twice);
    const ProbeCollider probe = press(1.5);
    stretched.stretch_next_frame(2);
    const EngineStepStats a = stretched.step(&probe, 1.0 / 30);
    const EngineStepStats c = long_frames.step(&probe, 1.0 / 30);
    EXPECT_EQ(a.iterations, c.iterations);
    EXPECT_TRUE(stretched.displacements_mm() == long_frames.displacements_mm())
        << stretched.name() << ": max difference "
        << (stretched.displacements_mm() - long_frames.displacements_mm()).cwiseAbs().maxCoeff();
    if (integrator == kExplicit) {
      EXPECT_EQ(a.iterations, 20);
      EXPECT_EQ(stretched.step(&probe, 1.0 / 30).iterations, 10) << "the next frame only";
    }
  }
  MsdsEngine engine = make_engine(b, kImplicit);
  EXPECT_THROW(engine.stretch_next_frame(0), std::invalid_argument);
  EXPECT_THROW(engine.stretch_next_frame(65), std::invalid_argument);
}

TEST(MsdsJobs, ResultsAreBitwiseIdenticalWithAndWithoutTwoThreads) {
  const Block b = make_block(30.0, {13, 9, 9});  // several node, spring and tet chunks
  ultrasim::testing::TwoThreadJobs jobs;
  for (auto integrator : {kExplicit, kImplicit}) {
    const MsdsSettings s =
        integrator == kImplicit ? with_step(0.01, 3) : with_step(0.5 * explicit_bound_s(b), 10);
    MsdsEngine serial = make_engine(b, integrator, s);
    MsdsEngine threaded = make_engine(b, integrator, s, &jobs);
    for (int frame = 0; frame < 3; ++frame) {
      const ProbeCollider probe = press(1.0 + 0.5 * frame);
      const auto a = serial.step(&probe, 1.0 / 30);
      const auto c = threaded.step(&probe, 1.0 / 30);
      EXPECT_EQ(a.iterations, c.iterations);
      EXPECT_EQ(a.contact_nodes, c.contact_nodes);
      EXPECT_EQ(a.contact_force_n, c.contact_force_n);
      EXPECT_EQ(a.relative_residual, c.relative_residual);
      ASSERT_TRUE(serial.displacements_mm() == threaded.displacements_mm())
          << serial.name() << " frame " << frame << ": max difference "
          << (serial.displacements_mm() - threaded.displacements_mm()).cwiseAbs().maxCoeff();
    }
  }
}

TEST(MsdsEngineKind, ReportsItsKindAndName) {
  const Block b = make_block();
  EXPECT_EQ(make_engine(b, kExplicit).kind(), EngineKind::kMsdsExplicit);
  EXPECT_EQ(make_engine(b, kImplicit).kind(), EngineKind::kMsdsImplicit);
  EXPECT_NE(make_engine(b, kExplicit).name(), make_engine(b, kImplicit).name());
}

}  // namespace
}  // namespace ultrasim::sim
