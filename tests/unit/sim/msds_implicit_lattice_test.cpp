// The implicit MSDS's springs by diagonal (internal: app/sim/src/msds_implicit_lattice.hpp): its
// forces, blocks and products against a spring-by-spring reference written here in plain Eigen
// (each spring from each of its nodes, as the engine did before), over several ranges, with
// collapsed and loose springs, and the damping force it gives a node on demand; and the AVX2
// build of its loops bitwise against the portable one.

#include "../../../app/sim/src/msds_implicit_lattice.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "block_fixture.hpp"
#include "lattice_springs.hpp"
#include "ultrasim/sim/msds.hpp"

namespace ultrasim::sim::msds_detail {
namespace {

using testing::Block;
using testing::springs_with_a_loose_one;

constexpr double kH = 0.004;  // s

// More nodes than one range holds, so that products cross a range's first node.
Block make_block() {
  return testing::make_block({24, 16, 12}, [](const Eigen::Vector3d& c) {
    return c.x() < 0 ? Material{1, "soft", 20.0} : Material{2, "stiff", 45.0};
  });
}

struct Vectors {
  std::vector<double> x, y, z;
  explicit Vectors(int n) : x(n + 64, 0.0), y(n + 64, 0.0), z(n + 64, 0.0) {}
  Eigen::Vector3d operator[](int i) const { return {x[i], y[i], z[i]}; }
  NodeArrays read() const { return {x.data(), y.data(), z.data()}; }
  MutableNodeArrays write() { return {x.data(), y.data(), z.data()}; }
};

// Every node moved and moving a little; node 0 squeezed onto its +x neighbour (a collapsed
// spring) and node 5 onto node 7 (coincident nodes with no spring).
void perturb(const Block& b, Vectors& position, Vectors& velocity, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-0.4, 0.4);
  for (int i = 0; i < b.mesh.node_count(); ++i) {
    const Eigen::Vector3d p =
        b.mesh.rest_positions_mm[i] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    position.x[i] = p.x();
    position.y[i] = p.y();
    position.z[i] = p.z();
    velocity.x[i] = 50.0 * noise(rng);
    velocity.y[i] = 50.0 * noise(rng);
    velocity.z[i] = 50.0 * noise(rng);
  }
  for (const auto& [i, onto] : {std::pair{0, 1}, std::pair{5, 7}}) {
    position.x[i] = position.x[onto];
    position.y[i] = position.y[onto];
    position.z[i] = position.z[onto];
  }
}

// One spring as seen from node `from`: its unit vector towards the other node (the rest
// direction if collapsed), elastic and damping force on `from`, and its block's two weights.
struct ReferenceSpring {
  Eigen::Vector3d dir, elastic, damping;
  double along = 0.0, across = 0.0;
};

ReferenceSpring reference_spring(const MsdsSpring& s, int from, const Block& b,
                                 const Vectors& position, const Vectors& velocity) {
  const int to = from == s.a ? s.b : s.a;
  const Eigen::Vector3d d = position[to] - position[from];
  const double length = d.norm();
  ReferenceSpring r;
  double transverse = 0.0;
  if (length > kImplicitCollapsedFraction * s.rest_length_mm) {
    r.dir = d / length;
    transverse = std::max(0.0, 1.0 - s.rest_length_mm / length);
  } else {
    r.dir = (b.mesh.rest_positions_mm[to] - b.mesh.rest_positions_mm[from]) / s.rest_length_mm;
  }
  r.elastic = s.stiffness_mn_per_mm * (length - s.rest_length_mm) * r.dir;
  r.damping = s.damping_mn_s_per_mm * (velocity[to] - velocity[from]).dot(r.dir) * r.dir;
  const double k = kH * kH * s.stiffness_mn_per_mm;
  r.along = kH * s.damping_mn_s_per_mm + k * (1.0 - transverse);
  r.across = k * transverse;
  return r;
}

double scale_of(const std::vector<Eigen::Vector3d>& v) {
  double largest = 0.0;
  for (const auto& x : v) largest = std::max(largest, x.lpNorm<Eigen::Infinity>());
  return largest;
}

TEST(ImplicitLattice, SumsAndProductsMatchEachSpringTakenFromEachOfItsNodes) {
  const Block b = make_block();
  const int n = b.mesh.node_count();
  ASSERT_GT(n, ImplicitLattice::kNodesPerRange);
  const std::vector<MsdsSpring> springs = springs_with_a_loose_one(b);
  ImplicitLattice lattice(b.mesh.rest_positions_mm, springs);
  ASSERT_GE(lattice.range_count(), 2);
  ASSERT_GT(lattice.diagonal_count(), 3);
  ASSERT_EQ(lattice.loose_spring_count(), 1);

  Vectors position(n), velocity(n), p(n), q(n);
  perturb(b, position, velocity, 11);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<double> diagonal(n + 64, 0.0);
  for (int i = 0; i < n; ++i) {
    p.x[i] = unit(rng);
    p.y[i] = unit(rng);
    p.z[i] = unit(rng);
    diagonal[i] = 1e-6 * (1.0 + unit(rng) * unit(rng));
  }
  for (int r = 0; r < lattice.range_count(); ++r) {
    lattice.compute_springs(r, position.read(), kH);
  }
  Vectors elastic(n), block_diagonal(n);
  lattice.sum_node_forces(0, n, elastic.write(), block_diagonal.write());
  for (int r = 0; r < lattice.range_count(); ++r) {
    lattice.multiply(r, diagonal.data(), p.read(), q.write());
  }

  std::vector<Eigen::Vector3d> want_elastic(n, Eigen::Vector3d::Zero()),
      want_damping = want_elastic, want_block = want_elastic, want_q = want_elastic;
  for (int i = 0; i < n; ++i) want_q[i] = diagonal[i] * p[i];
  for (const MsdsSpring& s : springs) {
    for (const int from : {s.a, s.b}) {
      const int to = from == s.a ? s.b : s.a;
      const ReferenceSpring r = reference_spring(s, from, b, position, velocity);
      want_elastic[from] += r.elastic;
      want_damping[from] += r.damping;
      want_block[from] += r.along * r.dir.cwiseProduct(r.dir) + Eigen::Vector3d::Constant(r.across);
      const Eigen::Vector3d dp = p[from] - p[to];
      want_q[from] += r.along * r.dir.dot(dp) * r.dir + r.across * dp;
    }
  }
  // Summed in another order and with 1 / l × d for d / l: rounding apart, no more.
  const double elastic_scale = scale_of(want_elastic), damping_scale = scale_of(want_damping),
               block_scale = scale_of(want_block), q_scale = scale_of(want_q);
  ASSERT_GT(elastic_scale, 0.0);
  ASSERT_GT(damping_scale, 0.0);
  for (int i = 0; i < n; ++i) {
    ASSERT_LT((elastic[i] - want_elastic[i]).lpNorm<Eigen::Infinity>(), 1e-12 * elastic_scale)
        << "node " << i;
    ASSERT_LT(
        (lattice.damping_force_on(i, velocity.read()) - want_damping[i]).lpNorm<Eigen::Infinity>(),
        1e-12 * damping_scale)
        << "node " << i;
    ASSERT_LT((block_diagonal[i] - want_block[i]).lpNorm<Eigen::Infinity>(), 1e-12 * block_scale)
        << "node " << i;
    ASSERT_LT((q[i] - want_q[i]).lpNorm<Eigen::Infinity>(), 1e-12 * q_scale) << "node " << i;
  }
  // The collapsed spring (node 0 onto node 1) pushes node 0 back along its rest direction.
  EXPECT_LT(elastic[0].dot(b.mesh.rest_positions_mm[1] - b.mesh.rest_positions_mm[0]), 0.0);
}

TEST(ImplicitLattice, Avx2LoopsGiveBitwiseWhatThePortableOnesGive) {
  const Block b = make_block();
  const int n = b.mesh.node_count();
  const std::vector<MsdsSpring> springs = springs_with_a_loose_one(b);
  ImplicitLattice portable(b.mesh.rest_positions_mm, springs, portable_implicit_kernels(),
                           portable_implicit_vector_kernels());
  ImplicitLattice fastest(b.mesh.rest_positions_mm, springs);
  Vectors position(n), velocity(n);
  perturb(b, position, velocity, 29);
  std::vector<double> diagonal(n + 64, 2e-6), mass(n + 64, 1e-6);
  std::vector<std::uint8_t> pinned(n + 64, 0), held(n + 64, 0);
  pinned[3] = held[40] = 1;

  struct Outputs {
    Vectors elastic, damping, block, q, inverse, rhs, r, z, p;
    explicit Outputs(int count)
        : elastic(count),
          damping(count),
          block(count),
          q(count),
          inverse(count),
          rhs(count),
          r(count),
          z(count),
          p(count) {}
  };
  const auto run = [&](ImplicitLattice& lattice, Outputs& out) {
    for (int r = 0; r < lattice.range_count(); ++r) {
      lattice.compute_springs(r, position.read(), kH);
    }
    lattice.sum_node_forces(0, n, out.elastic.write(), out.block.write());
    for (int r = 0; r < lattice.range_count(); ++r) {
      lattice.multiply(r, diagonal.data(), velocity.read(), out.q.write());
    }
    const StartRows rows{pinned.data(),       held.data(),      mass.data(),
                         diagonal.data(),     out.block.read(), velocity.read(),
                         out.elastic.read(),  out.q.read(),     kH,
                         out.inverse.write(), out.rhs.write(),  out.r.write(),
                         out.z.write(),       out.p.write()};
    lattice.vector_kernels().start_rows(rows, 0, n);
    const CgVectors cg{velocity.write(), out.r.write(), out.z.write(),
                       out.p.write(),    out.q.read(),  out.inverse.read()};
    Vectors saved = velocity;
    lattice.vector_kernels().cg_update(cg, 0.37, 0, n);
    lattice.vector_kernels().cg_direction(cg, 0.61, 0, n);
    velocity = saved;
  };
  Outputs a(n), f(n);
  run(portable, a);
  run(fastest, f);
  for (const auto& [x, y] :
       {std::pair{&a.elastic, &f.elastic}, std::pair{&a.block, &f.block}, std::pair{&a.q, &f.q},
        std::pair{&a.inverse, &f.inverse}, std::pair{&a.rhs, &f.rhs}, std::pair{&a.r, &f.r},
        std::pair{&a.z, &f.z}, std::pair{&a.p, &f.p}}) {
    EXPECT_EQ(x->x, y->x);
    EXPECT_EQ(x->y, y->y);
    EXPECT_EQ(x->z, y->z);
  }
  // Rows of nodes that do not move (pinned 3, held 40) are zero, and stay so.
  for (const int i : {3, 40}) {
    EXPECT_EQ(f.inverse[i], Eigen::Vector3d::Zero());
    EXPECT_EQ(f.rhs[i], Eigen::Vector3d::Zero());
    EXPECT_EQ(f.p[i], Eigen::Vector3d::Zero());
  }
  EXPECT_NE(f.rhs[4], Eigen::Vector3d::Zero());
  EXPECT_NE(f.p[4], Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace ultrasim::sim::msds_detail
