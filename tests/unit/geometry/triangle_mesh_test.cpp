#include "ultrasim/geometry/triangle_mesh.hpp"

#include <gtest/gtest.h>

namespace ultrasim::geometry {
namespace {

// An axis-aligned box [0, a] × [0, b] × [0, c], two outward triangles per face.
TriangleMesh box(double a, double b, double c) {
  TriangleMesh mesh;
  for (int v = 0; v < 8; ++v)
    mesh.vertices_mm.emplace_back(a * (v & 1), b * ((v >> 1) & 1), c * (v >> 2));
  mesh.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                    {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return mesh;
}

TEST(TriangleMesh, BoxVolumeAndAreaAreExact) {
  const TriangleMesh mesh = box(2, 3, 5);
  EXPECT_NEAR(enclosed_volume_mm3(mesh), 30.0, 1e-12);
  EXPECT_NEAR(surface_area_mm2(mesh), 2 * (6 + 10 + 15), 1e-12);
  EXPECT_TRUE(check_closed_oriented(mesh).closed_and_oriented());
}

TEST(TriangleMesh, VolumeDoesNotDependOnWhereTheMeshIs) {
  TriangleMesh mesh = box(2, 3, 5);
  for (auto& v : mesh.vertices_mm) v += Eigen::Vector3d(1e5, -2e5, 3e5);
  EXPECT_NEAR(enclosed_volume_mm3(mesh), 30.0, 1e-9);
}

TEST(TriangleMesh, InwardFacingSurfaceHasNegativeVolume) {
  TriangleMesh mesh = box(1, 1, 1);
  for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  EXPECT_NEAR(enclosed_volume_mm3(mesh), -1.0, 1e-12);
  EXPECT_TRUE(check_closed_oriented(mesh).closed_and_oriented());  // consistent, just inward
}

TEST(TriangleMesh, CheckFindsHolesFlipsDuplicatesAndDegenerates) {
  TriangleMesh open = box(1, 1, 1);
  open.triangles.pop_back();
  EXPECT_EQ(check_closed_oriented(open).boundary_edges, 3);
  EXPECT_FALSE(check_closed_oriented(open).closed_and_oriented());

  TriangleMesh flipped = box(1, 1, 1);
  std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
  const MeshTopologyReport flip = check_closed_oriented(flipped);
  EXPECT_EQ(flip.misoriented_edges, 3);
  EXPECT_EQ(flip.boundary_edges, 0);
  EXPECT_FALSE(flip.closed_and_oriented());

  TriangleMesh doubled = box(1, 1, 1);
  doubled.triangles.push_back(doubled.triangles[0]);
  EXPECT_EQ(check_closed_oriented(doubled).non_manifold_edges, 3);

  TriangleMesh degenerate = box(1, 1, 1);
  degenerate.triangles.push_back({0, 0, 1});
  degenerate.triangles.push_back({0, 1, 99});
  EXPECT_EQ(check_closed_oriented(degenerate).degenerate_triangles, 2);
}

TEST(TriangleMesh, VertexNormalsPointOutOfTheBoxCorners) {
  const TriangleMesh mesh = box(1, 1, 1);
  const auto normals = vertex_normals(mesh);
  const Eigen::Vector3d centre(0.5, 0.5, 0.5);
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    EXPECT_NEAR(normals[v].norm(), 1.0, 1e-12);
    EXPECT_GT(normals[v].dot(mesh.vertices_mm[v] - centre), 0.0) << v;
  }
}

TEST(TriangleMesh, UnusedVertexGetsZeroNormal) {
  TriangleMesh mesh = box(1, 1, 1);
  mesh.vertices_mm.emplace_back(9, 9, 9);
  EXPECT_EQ(vertex_normals(mesh).back(), Eigen::Vector3d::Zero());
}

}  // namespace
}  // namespace ultrasim::geometry
