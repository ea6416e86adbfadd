// The explicit MSDS's SIMD kernels (internal: app/sim/src/msds_kernels.hpp): the AVX2 kernels give
// bitwise what the portable ones give, and a sweep split into ranges gives bitwise what one sweep
// gives, collapsed springs and loose springs included.

#include "../../../app/sim/src/msds_kernels.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <random>
#include <vector>

#include "../../../app/sim/src/msds_spring_lattice.hpp"
#include "../../../app/sim/src/msds_task_team.hpp"
#include "../../../app/sim/src/msds_tet_lattice.hpp"
#include "block_fixture.hpp"
#include "lattice_springs.hpp"
#include "two_thread_jobs.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim::msds_detail {
namespace {

using testing::Block;
using testing::springs_with_a_loose_one;

Block make_block() {
  return testing::make_block({11, 6, 7}, [](const Eigen::Vector3d& c) {
    return c.x() < 0 ? Material{1, "soft", 20.0} : Material{2, "stiff", 45.0};
  });
}

// A perturbed state: every node moved and moving a little; node 0 squeezed onto its +x neighbour
// (a collapsed spring) and node 5 onto node 5 + 2 (coincident nodes with no spring).
FloatNodeState perturbed_state(const Block& b) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.4, 0.4);
  FloatNodeState s;
  s.assign_zero(b.mesh.node_count());
  for (int i = 0; i < b.mesh.node_count(); ++i) {
    const Eigen::Vector3d p =
        b.mesh.rest_positions_mm[i] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    s.set(i, p, 50.0 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  for (int i : {0, 5}) {
    const int onto = i == 0 ? 1 : 7;
    s.x[i] = s.x[onto];
    s.y[i] = s.y[onto];
    s.z[i] = s.z[onto];
  }
  return s;
}

struct Forces {
  std::vector<float> x, y, z;
  bool operator==(const Forces&) const = default;
};

// Forces on every node from sweeps over [0, n) split at `splits`, in blocks of `block` nodes.
Forces sweep_forces(const SpringLattice& lattice, const FloatNodeState& state, int node_count,
                    std::vector<int> splits, int block) {
  splits.insert(splits.begin(), 0);
  splits.push_back(node_count);
  Forces out{std::vector<float>(node_count + kNodePadding),
             std::vector<float>(node_count + kNodePadding),
             std::vector<float>(node_count + kNodePadding)};
  std::vector<float> f(3 * (block + kNodePadding));
  for (std::size_t r = 0; r + 1 < splits.size(); ++r) {
    SpringLattice::Sweep sweep = lattice.make_sweep(splits[r], splits[r + 1]);
    lattice.start_sweep(sweep, state);
    for (int begin = splits[r]; begin < splits[r + 1]; begin += block) {
      const int end = std::min(splits[r + 1], begin + block);
      float* fx = f.data();
      float* fy = fx + block + kNodePadding;
      float* fz = fy + block + kNodePadding;
      lattice.block_forces(sweep, state, begin, end, fx, fy, fz);
      for (int i = begin; i < end; ++i) {
        out.x[i] = fx[i - begin];
        out.y[i] = fy[i - begin];
        out.z[i] = fz[i - begin];
      }
    }
  }
  return out;
}

bool has_avx2_kernels() {
  return fastest_kernels().slot_forces != portable_kernels().slot_forces;
}

TEST(MsdsKernels, SweepsSplitIntoRangesAndBlocksGiveBitwiseTheSameForces) {
  const Block b = make_block();
  const int n = b.mesh.node_count();
  const SpringLattice lattice(b.mesh.rest_positions_mm, springs_with_a_loose_one(b), 0.1);
  EXPECT_GT(lattice.diagonal_count(), 3);
  EXPECT_EQ(lattice.loose_spring_count(), 1);
  const FloatNodeState state = perturbed_state(b);
  const Forces whole = sweep_forces(lattice, state, n, {}, 64);
  EXPECT_TRUE(whole == sweep_forces(lattice, state, n, {64, 192}, 64));
  EXPECT_TRUE(whole == sweep_forces(lattice, state, n, {128}, 32));
  // Action and reaction: the forces sum to (nearly) nothing.
  double sum = 0.0, scale = 0.0;
  for (int i = 0; i < n; ++i) {
    sum += whole.x[i];
    scale += std::abs(whole.x[i]);
  }
  EXPECT_LT(std::abs(sum), 1e-5 * scale);
}

TEST(MsdsKernels, AtRestEveryForceIsExactlyZero) {
  const Block b = make_block();
  const SpringLattice lattice(b.mesh.rest_positions_mm, springs_with_a_loose_one(b), 0.1);
  FloatNodeState rest;
  rest.assign_zero(b.mesh.node_count());
  for (int i = 0; i < b.mesh.node_count(); ++i) {
    rest.set(i, b.mesh.rest_positions_mm[i], Eigen::Vector3d::Zero());
  }
  const Forces f = sweep_forces(lattice, rest, b.mesh.node_count(), {100}, 64);
  for (int i = 0; i < b.mesh.node_count(); ++i) {
    ASSERT_EQ(f.x[i], 0.0f) << i;
    ASSERT_EQ(f.y[i], 0.0f) << i;
    ASSERT_EQ(f.z[i], 0.0f) << i;
  }
}

TEST(MsdsKernels, Avx2SpringForcesEqualThePortableOnesBitwise) {
  if (!has_avx2_kernels()) GTEST_SKIP() << "no AVX2 on this CPU";
  const Block b = make_block();
  const int n = b.mesh.node_count();
  const auto springs = springs_with_a_loose_one(b);
  const SpringLattice portable(b.mesh.rest_positions_mm, springs, 0.1, portable_kernels());
  const SpringLattice avx2(b.mesh.rest_positions_mm, springs, 0.1, fastest_kernels());
  const FloatNodeState state = perturbed_state(b);
  const Forces p = sweep_forces(portable, state, n, {96}, 64);
  EXPECT_TRUE(p == sweep_forces(avx2, state, n, {96}, 64));
  EXPECT_TRUE(std::isfinite(p.x[0]) && p.x[0] != 0.0f) << "the collapsed spring pushes node 0";
}

TEST(MsdsKernels, Avx2ForwardEulerEqualsThePortableOneBitwise) {
  if (!has_avx2_kernels()) GTEST_SKIP() << "no AVX2 on this CPU";
  constexpr int kNodes = 200;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> value(-2.0, 2.0);
  struct Arrays {
    std::vector<double> x, y, z, vx, vy, vz, mass, inverse_mass, clearance;
    FloatNodeState next;
  };
  Arrays start;
  for (auto* a : {&start.x, &start.y, &start.z, &start.vx, &start.vy, &start.vz, &start.mass,
                  &start.inverse_mass, &start.clearance}) {
    a->resize(kNodes + kNodePadding);
    for (double& v : *a) v = value(rng);
  }
  for (int i = 0; i < kNodes + kNodePadding; ++i) {
    start.mass[i] = 1e-3 * (3.0 + start.mass[i]);
    start.inverse_mass[i] = i % 7 == 0 ? 0.0 : 1.0 / start.mass[i];  // some pinned
  }
  start.next.assign_zero(kNodes);
  std::vector<float> f(3 * (kNodes + kNodePadding));
  for (float& v : f) v = static_cast<float>(100.0 * value(rng));
  const auto run = [&](const SpringKernels& kernels, Arrays a) {
    const ExplicitNodeArrays nodes{
        a.x.data(),        a.y.data(),  a.z.data(),    a.vx.data(),
        a.vy.data(),       a.vz.data(), a.mass.data(), a.inverse_mass.data(),
        a.clearance.data()};
    const float* fx = f.data();
    const NodeUpdateSums sums =
        kernels.forward_euler(nodes, 0, kNodes, 1e-3, fx, fx + kNodes + kNodePadding,
                              fx + 2 * (kNodes + kNodePadding), a.next);
    return std::pair{sums.kinetic_energy_uj, a};
  };
  const auto [energy_portable, portable] = run(portable_kernels(), start);
  const auto [energy_avx2, avx2] = run(fastest_kernels(), start);
  EXPECT_EQ(energy_portable, energy_avx2);
  for (int i = 0; i < kNodes; ++i) {
    ASSERT_EQ(portable.x[i], avx2.x[i]) << i;
    ASSERT_EQ(portable.vz[i], avx2.vz[i]) << i;
    ASSERT_EQ(portable.clearance[i], avx2.clearance[i]) << i;
    ASSERT_EQ(portable.next.y[i], avx2.next.y[i]) << i;
    ASSERT_EQ(portable.next.vx[i], avx2.next.vx[i]) << i;
  }
}

TEST(MsdsKernels, TetLatticeCountsExactlyTheTetsWithNoPositiveVolume) {
  const Block b = make_block();
  const int n = b.mesh.node_count();
  const TetLattice lattice(b.mesh.tets, n);
  std::mt19937 rng(4);
  // Shaken hard enough to fold some tets, and one tet made exactly flat (volume 0 counts).
  std::uniform_real_distribution<double> noise(-2.5, 2.5);
  std::vector<double> x(n + kNodePadding, 0.0), y = x, z = x;
  for (int i = 0; i < n; ++i) {
    x[i] = b.mesh.rest_positions_mm[i].x() + noise(rng);
    y[i] = b.mesh.rest_positions_mm[i].y() + noise(rng);
    z[i] = b.mesh.rest_positions_mm[i].z() + noise(rng);
  }
  const geometry::Tet& flat = b.mesh.tets[17];
  x[flat[3]] = x[flat[0]];
  y[flat[3]] = y[flat[0]];
  z[flat[3]] = z[flat[0]];
  int expected = 0;
  for (const auto& t : b.mesh.tets)
    expected += six_signed_volume(x.data(), y.data(), z.data(), t) <= 0.0;
  int counted = 0;
  for (int c = 0; c < lattice.chunk_count(); ++c)
    counted += lattice.count(c, x.data(), y.data(), z.data());
  EXPECT_GT(expected, 10);
  EXPECT_LT(expected, b.mesh.tet_count() / 2);
  EXPECT_EQ(counted, expected);
  if (has_avx2_kernels()) {
    EXPECT_GT(lattice.pattern_count(), 5);
    EXPECT_EQ(lattice.loose_tet_count(), 0);
  }
}

// A job system that says it has two threads but runs the tasks one after another, last first:
// the task that starts first must lead, and a helper that finds the run over must return.
class OneAfterAnotherJobs final : public hal::JobSystem {
 public:
  int thread_count() const override { return 2; }
  void run(int task_count, void (*task)(void*, int), void* context) override {
    for (int i = task_count - 1; i >= 0; --i) task(context, i);
  }
};

// Runs 200 stages of 7 items each through the team; returns how often each item ran.
std::vector<int> runs_of_each_item(hal::JobSystem& jobs) {
  TaskTeam team(&jobs);
  std::vector<std::atomic<int>> runs(200 * 7);
  team.run([&] {
    for (int stage = 0; stage < 200; ++stage) {
      team.for_each(7, [&](int item) { runs[stage * 7 + item].fetch_add(1); });
    }
  });
  std::vector<int> out;
  for (const auto& r : runs) out.push_back(r.load());
  return out;
}

TEST(MsdsTaskTeam, EveryItemOfEveryStageRunsOnceWithHelpersOrWithout) {
  ultrasim::testing::TwoThreadJobs concurrent;
  OneAfterAnotherJobs sequential;
  const std::vector<int> once(200 * 7, 1);
  EXPECT_EQ(runs_of_each_item(concurrent), once);
  EXPECT_EQ(runs_of_each_item(sequential), once);
}

}  // namespace
}  // namespace ultrasim::sim::msds_detail
