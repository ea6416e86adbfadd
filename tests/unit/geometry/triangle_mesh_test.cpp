#include "ultrasim/geometry/triangle_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

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

// A wrinkled sheet of n × n vertices: triangles of every size and orientation, a few slivers.
TriangleMesh wrinkled_sheet(int n) {
  TriangleMesh mesh;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> jitter(-0.4, 0.4);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh.vertices_mm.emplace_back(i + jitter(rng), j + jitter(rng),
                                    std::sin(0.7 * i) * std::cos(0.3 * j) + jitter(rng));
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
      mesh.triangles.push_back({a, b, c});
      mesh.triangles.push_back({a, c, d});
    }
  }
  return mesh;
}

TEST(SharedVertexNormals, GiveComputeVertexNormalsBitsInAnySplit) {
  TriangleMesh mesh = wrinkled_sheet(40);
  mesh.triangles.push_back({0, 0, 1});  // degenerate: a corner twice
  std::shuffle(mesh.triangles.begin(), mesh.triangles.end(), std::mt19937(11));
  mesh.vertices_mm.emplace_back(9, 9, 9);  // in no triangle
  std::vector<Eigen::Vector3d> reference(mesh.vertices_mm.size());
  compute_vertex_normals(mesh.vertices_mm, mesh.triangles, reference);

  SharedVertexNormals shared(mesh.vertex_count(), mesh.triangles);
  for (const int pieces : {1, 3, 17}) {
    SCOPED_TRACE(pieces);
    std::vector<Eigen::Vector3d> normals(mesh.vertices_mm.size(), Eigen::Vector3d::Constant(7));
    // Backwards, so no piece runs in the order one loop would.
    for (int p = pieces - 1; p >= 0; --p) {
      shared.triangle_normals(mesh.vertices_mm, p * mesh.triangle_count() / pieces,
                              (p + 1) * mesh.triangle_count() / pieces);
    }
    for (int p = pieces - 1; p >= 0; --p) {
      shared.vertex_normals(p * mesh.vertex_count() / pieces,
                            (p + 1) * mesh.vertex_count() / pieces, normals);
    }
    for (int v = 0; v < mesh.vertex_count(); ++v) {
      for (int a = 0; a < 3; ++a) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(normals[v][a]),
                  std::bit_cast<std::uint64_t>(reference[v][a]))
            << "vertex " << v << " axis " << a;
      }
    }
  }
  EXPECT_EQ(reference.back(), Eigen::Vector3d::Zero());
  EXPECT_NEAR(reference.front().norm(), 1.0, 1e-12);
}

TEST(SharedVertexNormals, RejectATriangleOutsideTheVertices) {
  const TriangleMesh mesh = box(1, 1, 1);
  EXPECT_THROW(SharedVertexNormals(7, mesh.triangles), std::invalid_argument);
  const std::vector<Triangle> negative = {{0, 1, -1}};
  EXPECT_THROW(SharedVertexNormals(8, negative), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::geometry
