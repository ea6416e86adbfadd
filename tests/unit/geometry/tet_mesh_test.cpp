#include "ultrasim/geometry/tet_mesh.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <map>
#include <set>

namespace ultrasim::geometry {
namespace {

GridSpec unit_grid(int n) {
  return GridSpec::spanning(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(n - 1.0),
                            Eigen::Vector3i::Constant(n));
}

TEST(TetMesh, FiveByFiveByFiveGridHas125NodesAnd320Tets) {
  const TetMesh mesh = make_grid_tet_mesh(unit_grid(5));
  EXPECT_EQ(mesh.node_count(), 125);
  EXPECT_EQ(mesh.tet_count(), 320);
}

TEST(TetMesh, PublishedGridSizeHas34875Tets) {
  const GridSpec grid =
      GridSpec::spanning(Eigen::Vector3d::Zero(), Eigen::Vector3d(62, 30, 30), {32, 16, 16});
  const TetMesh mesh = make_grid_tet_mesh(grid);
  EXPECT_EQ(mesh.node_count(), 8192);
  EXPECT_EQ(mesh.tet_count(), 34875);
}

TEST(TetMesh, TetsArePositiveAndFillTheBoxExactly) {
  const GridSpec grid =
      GridSpec::spanning(Eigen::Vector3d(-1, 2, 3), Eigen::Vector3d(5, 4, 10), {4, 3, 6});
  const TetMesh mesh = make_grid_tet_mesh(grid);
  double total = 0.0;
  for (const Tet& t : mesh.tets) {
    const auto& p = mesh.rest_positions_mm;
    const double v = signed_tet_volume(p[t[0]], p[t[1]], p[t[2]], p[t[3]]);
    EXPECT_GT(v, 0.0);
    total += v;
  }
  EXPECT_NEAR(total, 6.0 * 2.0 * 7.0, 1e-9);
}

TEST(TetMesh, EveryInteriorFaceIsSharedByExactlyTwoTets) {
  const TetMesh mesh = make_grid_tet_mesh(unit_grid(5));
  std::map<std::array<std::int32_t, 3>, int> face_uses;
  for (const Tet& t : mesh.tets) {
    for (int skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      int n = 0;
      for (int c = 0; c < 4; ++c)
        if (c != skip) f[n++] = t[c];
      std::sort(f.begin(), f.end());
      ++face_uses[f];
    }
  }
  int boundary = 0, interior = 0;
  for (const auto& [face, uses] : face_uses) {
    ASSERT_LE(uses, 2) << "a face is shared by more than two tets: the mesh does not conform";
    // A face on the box surface has all three nodes on one side of the box.
    bool on_surface = false;
    for (int axis = 0; axis < 3 && !on_surface; ++axis) {
      for (double side : {0.0, 4.0}) {
        bool all = true;
        for (auto node : face) all &= mesh.rest_positions_mm[node][axis] == side;
        on_surface |= all;
      }
    }
    if (on_surface) {
      EXPECT_EQ(uses, 1);
      ++boundary;
    } else {
      EXPECT_EQ(uses, 2) << "an interior face is used by one tet only: a crack in the mesh";
      ++interior;
    }
  }
  EXPECT_EQ(boundary, 6 * 16 * 2);  // each boundary square cut into two triangles
  EXPECT_EQ(interior, (320 * 4 - boundary) / 2);
}

TEST(TetMesh, BoundaryFacesPointOutwards) {
  const TetMesh mesh = make_grid_tet_mesh(unit_grid(4));
  const auto faces = boundary_faces(mesh);
  ASSERT_EQ(faces.size(), 6u * 9u * 2u);
  const Eigen::Vector3d centre = Eigen::Vector3d::Constant(1.5);
  for (const auto& f : faces) {
    const auto& p = mesh.rest_positions_mm;
    const Eigen::Vector3d normal = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
    const Eigen::Vector3d mid = (p[f[0]] + p[f[1]] + p[f[2]]) / 3.0;
    EXPECT_GT(normal.dot(mid - centre), 0.0);
  }
  const auto edges = unique_edges(faces);
  // Surface of a 3×3×3-cell box: 12 box edges × 3 segments + grid lines and diagonals on faces.
  EXPECT_EQ(edges.size(), 6u * (2u * 3u * 4u + 9u) - 12u * 3u);
}

// The wireframe's levels of detail on a 3×3×3-node grid (2 cells a side) and a 5×5×5 one.
TEST(TetMesh, GridSurfaceLinesThinOutByStride) {
  // Every grid line: each face's 12 segments, the box's 12 edges (2 segments each) shared by two
  // faces.
  EXPECT_EQ(grid_surface_lines(unit_grid(3), 1).size(), 6u * 12u - 12u * 2u);
  // Every 2nd node: only the box's edges remain.
  EXPECT_EQ(grid_surface_lines(unit_grid(3), 2).size(), 12u * 2u);
  const auto fine = grid_surface_lines(unit_grid(5), 1);
  const auto coarse = grid_surface_lines(unit_grid(5), 2);
  // 5×5 nodes a face: 2 × 5 lines of 4 segments = 40; the box's edges (4 segments) shared.
  EXPECT_EQ(fine.size(), 6u * 40u - 12u * 4u);
  // Lines through nodes 0, 2, 4: 2 × 3 lines of 4 segments = 24 a face.
  EXPECT_EQ(coarse.size(), 6u * 24u - 12u * 4u);
  // A subset of the tets' surface edges, each once, lower index first.
  const auto all = unique_edges(boundary_faces(make_grid_tet_mesh(unit_grid(5))));
  std::set<std::array<std::int32_t, 2>> surface(all.begin(), all.end());
  std::set<std::array<std::int32_t, 2>> seen;
  for (const auto& e : fine) {
    EXPECT_LT(e[0], e[1]);
    EXPECT_TRUE(surface.contains(e));
    EXPECT_TRUE(seen.insert(e).second) << "drawn twice";
  }
}

TEST(TetMesh, RejectsDegenerateGrids) {
  EXPECT_THROW(GridSpec::spanning(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones(), {1, 2, 2}),
               std::invalid_argument);
  EXPECT_THROW(GridSpec::spanning(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 1), {2, 2, 2}),
               std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::geometry
