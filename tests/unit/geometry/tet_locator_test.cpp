#include "ultrasim/geometry/tet_locator.hpp"

#include <gtest/gtest.h>

#include <random>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::geometry {
namespace {

TetMesh box_mesh() {
  return make_grid_tet_mesh(
      GridSpec::spanning(Eigen::Vector3d(-10, -5, 0), Eigen::Vector3d(10, 5, 12), {7, 4, 5}));
}

Eigen::Vector3d interpolate(const TetMesh& mesh, std::span<const Eigen::Vector3d> positions,
                            const TetLocation& loc) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int c = 0; c < 4; ++c) p += loc.barycentric[c] * positions[mesh.tets[loc.tet][c]];
  return p;
}

TEST(TetLocator, FindsEveryPointInsideTheRestMesh) {
  const TetMesh mesh = box_mesh();
  const TetLocator locator(mesh);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-10, 10), uy(-5, 5), uz(0, 12);
  for (int n = 0; n < 2000; ++n) {
    const Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
    const auto loc = locator.locate(p);
    ASSERT_TRUE(loc.has_value()) << p.transpose();
    EXPECT_GE(loc->barycentric.minCoeff(), -1e-9);
    EXPECT_NEAR(loc->barycentric.sum(), 1.0, 1e-12);
    EXPECT_LT((interpolate(mesh, mesh.rest_positions_mm, *loc) - p).norm(), 1e-9);
  }
}

TEST(TetLocator, ReportsPointsOutsideAsOutside) {
  const TetLocator locator(box_mesh());
  EXPECT_FALSE(locator.locate({0, 0, -0.01}).has_value());
  EXPECT_FALSE(locator.locate({10.5, 0, 5}).has_value());
  EXPECT_FALSE(locator.locate({0, 0, 1e9}).has_value());
  EXPECT_FALSE(locator.locate({std::nan(""), 0, 1}).has_value());
}

TEST(TetLocator, FollowsTheDeformedMeshAndMapsBackToRest) {
  const TetMesh mesh = box_mesh();
  std::vector<Eigen::Vector3d> deformed = mesh.rest_positions_mm;
  // A smooth compression under a "probe" at the top centre keeps every tet positive.
  for (auto& p : deformed) {
    const double falloff = std::exp(-(p.x() * p.x() + p.y() * p.y()) / 30.0);
    p.z() += 3.0 * falloff * (1.0 - p.z() / 12.0);
  }
  TetLocator locator(mesh);
  locator.rebuild(deformed);
  EXPECT_EQ(locator.degenerate_tet_count(), 0);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> pick(0, mesh.tet_count() - 1);
  std::uniform_real_distribution<double> u01(0, 1);
  for (int n = 0; n < 1000; ++n) {
    const int t = pick(rng);
    Eigen::Vector4d w(u01(rng), u01(rng), u01(rng), u01(rng));
    w /= w.sum();
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (int c = 0; c < 4; ++c) p += w[c] * deformed[mesh.tets[t][c]];
    const auto loc = locator.locate(p);
    ASSERT_TRUE(loc.has_value());
    EXPECT_LT((interpolate(mesh, deformed, *loc) - p).norm(), 1e-9);
    if (w.minCoeff() > 1e-6) {  // strictly inside: the same tet, the same weights
      EXPECT_EQ(loc->tet, t);
      EXPECT_LT((loc->barycentric - w).norm(), 1e-9);
    }
  }
}

TEST(TetLocator, LeavesInvertedTetsOut) {
  const TetMesh mesh = box_mesh();
  std::vector<Eigen::Vector3d> squashed = mesh.rest_positions_mm;
  for (auto& p : squashed) p.z() = 0.0;  // every tet flat
  TetLocator locator(mesh);
  locator.rebuild(squashed);
  EXPECT_EQ(locator.degenerate_tet_count(), mesh.tet_count());
  EXPECT_FALSE(locator.locate({0, 0, 0}).has_value());
}

}  // namespace
}  // namespace ultrasim::geometry
