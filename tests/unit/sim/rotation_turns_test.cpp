// The corotational FEM's turn check: the portable kernel against the check written with Eigen
// (reference_turn), and the fastest kernel (AVX2 here) against the portable one, bitwise.

#include "../../../app/sim/src/rotation_turns.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "../../../app/sim/src/polar_rotation.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::sim::corotational_detail {
namespace {

Eigen::Matrix3d rotation_about(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

// A pressed, turned block whose tets each hold a rotation near their own, some far from it (a
// half turn away: lost), a few inverted or squeezed flat (lost too).
struct TurnScene {
  geometry::TetMesh mesh;
  std::vector<Eigen::Matrix<double, 3, 4>> gradients;
  std::vector<Eigen::Matrix3d> rotations;
  Eigen::VectorXd u;

  explicit TurnScene(unsigned seed) {
    mesh = geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(
        Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(20, 16, 12), Eigen::Vector3i(7, 6, 5)));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    const Eigen::Matrix3d turn = rotation_about({unit(rng), unit(rng), 1.0}, 0.6 * unit(rng));
    u.resize(3 * mesh.node_count());
    for (int n = 0; n < mesh.node_count(); ++n) {
      const Eigen::Vector3d& p = mesh.rest_positions_mm[n];
      // A dent under the middle, turned as a whole, and a little noise.
      const double dent =
          4.0 * std::exp(-((p.x() - 10) * (p.x() - 10) + (p.y() - 8) * (p.y() - 8)) / 40.0) *
          (1.0 - p.z() / 12.0);
      const Eigen::Vector3d moved = turn * (p + Eigen::Vector3d(0.0, 0.0, dent)) +
                                    0.15 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
      u.segment<3>(3 * n) = moved - p;
    }
    // Flatten or invert a few tets by moving single nodes through their neighbours.
    for (int k = 0; k < 6; ++k) {
      const int n = static_cast<int>((k * 37 + 11) % mesh.node_count());
      u.segment<3>(3 * n) += Eigen::Vector3d(0.0, 0.0, k % 2 == 0 ? 3.2 : -3.2);
    }
    for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
      const geometry::Tet& tet = mesh.tets[t];
      Eigen::Matrix3d edges;
      for (int b = 1; b < 4; ++b) {
        edges.col(b - 1) = mesh.rest_positions_mm[tet[b]] - mesh.rest_positions_mm[tet[0]];
      }
      // Node b's gradient: row b − 1 of the edges' inverse; node 0's: minus their sum.
      const Eigen::Matrix3d inverse = edges.inverse();
      Eigen::Matrix<double, 3, 4> g;
      g.rightCols<3>() = inverse.transpose();
      g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
      gradients.push_back(g);
      const Eigen::Matrix3d held = polar_rotation(gradient(static_cast<int>(t)));
      if (t % 29 == 5) {
        rotations.push_back(held * rotation_about({1, 0, 0}, 3.0));  // a half turn away
      } else {
        // A little behind the tet's own rotation: the turn the check measures.
        rotations.push_back(held *
                            rotation_about({unit(rng), unit(rng), unit(rng)}, 0.05 * unit(rng)));
      }
    }
  }

  // As CorotationalFem::deformation_gradient: Σ_b (x_b − x_0) g_bᵀ.
  Eigen::Matrix3d gradient(int t) const {
    const geometry::Tet& tet = mesh.tets[t];
    const auto x = [&](int a) -> Eigen::Vector3d {
      return mesh.rest_positions_mm[tet[a]] + u.segment<3>(3 * tet[a]);
    };
    Eigen::Matrix3d e;
    e.col(0) = x(1) - x(0);
    e.col(1) = x(2) - x(0);
    e.col(2) = x(3) - x(0);
    return e.lazyProduct(gradients[t].rightCols<3>().transpose());
  }

  TurnInputs inputs() const {
    return {mesh.tets.data(), mesh.rest_positions_mm.data(), u.data(), gradients.data(),
            rotations.data()};
  }
  int tet_count() const { return static_cast<int>(mesh.tets.size()); }
};

std::vector<int> every_tet(int count) {
  std::vector<int> tets(static_cast<std::size_t>(count));
  for (int t = 0; t < count; ++t) tets[t] = t;
  return tets;
}

TEST(RotationTurns, PortableKernelMatchesTheCheckWrittenWithEigen) {
  int lost = 0, turned = 0;
  for (const unsigned seed : {1u, 2u, 3u}) {
    const TurnScene scene(seed);
    std::vector<double> turns(scene.tet_count(), -1.0);
    portable_turn_kernel()(scene.inputs(), every_tet(scene.tet_count()), turns.data());
    for (int t = 0; t < scene.tet_count(); ++t) {
      const double expected = reference_turn(scene.rotations[t], scene.gradient(t));
      if (std::isinf(expected)) {
        EXPECT_TRUE(std::isinf(turns[t])) << "seed " << seed << " tet " << t;
        ++lost;
      } else {
        EXPECT_NEAR(turns[t], expected, 1e-12 * std::max(1.0, expected))
            << "seed " << seed << " tet " << t;
        turned += expected > 1e-3;
      }
    }
  }
  // Not vacuous: lost tets (inverted, flattened, a half turn away) and turned ones.
  EXPECT_GT(lost, 30);
  EXPECT_GT(turned, 1000);
}

TEST(RotationTurns, FastestKernelGivesThePortableKernelsBits) {
  for (const unsigned seed : {4u, 5u}) {
    const TurnScene scene(seed);
    const int n = scene.tet_count();
    // Lists of every length up to a few lane groups, shuffled, with repeats: the AVX2 kernel's
    // last group repeats its last tet.
    std::mt19937 rng(seed);
    std::vector<std::vector<int>> lists;
    for (int length = 1; length <= 13; ++length) {
      std::vector<int> list;
      for (int i = 0; i < length; ++i) list.push_back(static_cast<int>(rng() % n));
      lists.push_back(list);
    }
    std::vector<int> all = every_tet(n);
    std::shuffle(all.begin(), all.end(), rng);
    lists.push_back(all);
    for (const std::vector<int>& list : lists) {
      std::vector<double> fastest(n, -1.0), portable(n, -1.0);
      fastest_turn_kernel()(scene.inputs(), list, fastest.data());
      portable_turn_kernel()(scene.inputs(), list, portable.data());
      for (int t = 0; t < n; ++t) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(fastest[t]),
                  std::bit_cast<std::uint64_t>(portable[t]))
            << "seed " << seed << ", list of " << list.size() << ", tet " << t;
      }
    }
  }
}

}  // namespace
}  // namespace ultrasim::sim::corotational_detail
