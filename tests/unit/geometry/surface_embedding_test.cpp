#include "ultrasim/geometry/surface_embedding.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "ultrasim/geometry/tet_mesh.hpp"

namespace ultrasim::geometry {
namespace {

TetMesh box_mesh() {
  return make_grid_tet_mesh(
      GridSpec::spanning(Eigen::Vector3d(-10, -5, 0), Eigen::Vector3d(10, 5, 12), {7, 4, 5}));
}

// Points inside the box, on its faces and corners, and a few up to 1.5 mm outside it (the way a
// surface closed half a voxel beyond the volume pokes out of the mesh).
std::vector<Eigen::Vector3d> sample_points() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-11.5, 11.5), uy(-6.5, 6.5), uz(-1.5, 13.5);
  std::vector<Eigen::Vector3d> points;
  for (int n = 0; n < 3000; ++n) points.emplace_back(ux(rng), uy(rng), uz(rng));
  points.emplace_back(-10, -5, 0);
  points.emplace_back(10, 5, 12);
  points.emplace_back(0, 5, 6);
  return points;
}

TEST(SurfaceEmbedding, RestPositionsAreReproduced) {
  const TetMesh mesh = box_mesh();
  const auto points = sample_points();
  const SurfaceEmbedding embedding(mesh, points);
  EXPECT_GT(embedding.outside_vertex_count(), 100);
  EXPECT_LT(embedding.outside_vertex_count(), static_cast<int>(points.size()));
  std::vector<Eigen::Vector3d> out(points.size());
  embedding.update(mesh.rest_positions_mm, out);
  for (std::size_t v = 0; v < points.size(); ++v) {
    EXPECT_LT((out[v] - points[v]).norm(), 1e-12) << points[v].transpose();
  }
  for (const EmbeddedVertex& e : embedding.vertices()) {
    double sum = 0;
    for (const double w : e.weights) sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-12);
  }
}

TEST(SurfaceEmbedding, InsideVerticesHaveWeightsInTheirTet) {
  const TetMesh mesh = box_mesh();
  const std::vector<Eigen::Vector3d> points{{0, 0, 6}, {3.3, -1.2, 0.4}, {9.9, 4.9, 11.9}};
  const SurfaceEmbedding embedding(mesh, points);
  EXPECT_EQ(embedding.outside_vertex_count(), 0);
  for (int v = 0; v < embedding.vertex_count(); ++v) {
    const EmbeddedVertex& e = embedding.vertices()[v];
    EXPECT_EQ(e.nodes, mesh.tets[embedding.tets()[v]]);
    for (const double w : e.weights) EXPECT_GE(w, -1e-9);
  }
}

TEST(SurfaceEmbedding, OutsideVertexUsesTheNearestBoundaryTet) {
  const TetMesh mesh = box_mesh();
  // 0.5 mm above the top face's centre: its tet touches the top face (z = 12) right below it.
  const std::vector<Eigen::Vector3d> points{{0.1, 0.2, 12.5}};
  const SurfaceEmbedding embedding(mesh, points);
  ASSERT_EQ(embedding.outside_vertex_count(), 1);
  const Tet& tet = mesh.tets[embedding.tets()[0]];
  int on_top = 0;
  for (const std::int32_t n : tet) on_top += mesh.rest_positions_mm[n].z() == 12.0;
  EXPECT_EQ(on_top, 3);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const std::int32_t n : tet) {
    lo = lo.cwiseMin(mesh.rest_positions_mm[n]);
    hi = hi.cwiseMax(mesh.rest_positions_mm[n]);
  }
  EXPECT_TRUE((lo.head<2>().array() <= Eigen::Array2d(0.1, 0.2)).all());
  EXPECT_TRUE((hi.head<2>().array() >= Eigen::Array2d(0.1, 0.2)).all());
}

// For a box-shaped mesh the nearest point of the mesh to an outside point is the point clamped
// into the box; the tet chosen must contain it (whichever of the tets sharing it).
TEST(SurfaceEmbedding, OutsideVerticesUseATetHoldingTheNearestMeshPoint) {
  const TetMesh mesh = box_mesh();
  const auto points = sample_points();
  const SurfaceEmbedding embedding(mesh, points);
  const Eigen::Vector3d lo(-10, -5, 0), hi(10, 5, 12);
  int outside = 0;
  for (std::size_t v = 0; v < points.size(); ++v) {
    const Eigen::Vector3d nearest = points[v].cwiseMax(lo).cwiseMin(hi);
    if (nearest == points[v]) continue;
    ++outside;
    const Tet& tet = mesh.tets[embedding.tets()[v]];
    const auto& x = mesh.rest_positions_mm;
    Eigen::Matrix3d edges;
    edges << x[tet[1]] - x[tet[0]], x[tet[2]] - x[tet[0]], x[tet[3]] - x[tet[0]];
    const Eigen::Vector3d l = edges.inverse() * (nearest - x[tet[0]]);
    EXPECT_GE(l.minCoeff(), -1e-9) << points[v].transpose();
    EXPECT_GE(1 - l.sum(), -1e-9) << points[v].transpose();
  }
  EXPECT_EQ(outside, embedding.outside_vertex_count());
}

TEST(SurfaceEmbedding, AffineDeformationMovesVerticesByTheSameMap) {
  const TetMesh mesh = box_mesh();
  const auto points = sample_points();
  const SurfaceEmbedding embedding(mesh, points);
  Eigen::Matrix3d a;
  a << 1.1, 0.2, -0.1,  //
      0.05, 0.8, 0.3,   //
      -0.2, 0.1, 1.3;
  const Eigen::Vector3d b(3.0, -7.0, 0.5);
  std::vector<Eigen::Vector3d> deformed;
  for (const auto& p : mesh.rest_positions_mm) deformed.push_back(a * p + b);
  std::vector<Eigen::Vector3d> out(points.size());
  embedding.update(deformed, out);
  for (std::size_t v = 0; v < points.size(); ++v) {
    EXPECT_LT((out[v] - (a * points[v] + b)).norm(), 1e-11) << points[v].transpose();
  }
}

TEST(SurfaceEmbedding, VerticesStayInTheirDeformedTet) {
  const TetMesh mesh = box_mesh();
  std::vector<Eigen::Vector3d> points;
  for (int n = 0; n < 200; ++n)
    points.emplace_back(-9.5 + 0.095 * n, 4.0 - 0.04 * n, 0.5 + 0.055 * n);
  const SurfaceEmbedding embedding(mesh, points);
  std::vector<Eigen::Vector3d> deformed = mesh.rest_positions_mm;
  for (auto& p : deformed)
    p.z() += 3.0 * std::exp(-(p.x() * p.x() + p.y() * p.y()) / 30.0) * (1 - p.z() / 12);
  std::vector<Eigen::Vector3d> out(points.size());
  embedding.update(deformed, out);
  for (int v = 0; v < embedding.vertex_count(); ++v) {
    const Tet& tet = mesh.tets[embedding.tets()[v]];
    Eigen::Matrix3d edges;
    edges << deformed[tet[1]] - deformed[tet[0]], deformed[tet[2]] - deformed[tet[0]],
        deformed[tet[3]] - deformed[tet[0]];
    const Eigen::Vector3d l = edges.inverse() * (out[v] - deformed[tet[0]]);
    EXPECT_GE(l.minCoeff(), -1e-9);
    EXPECT_GE(1 - l.sum(), -1e-9);
  }
}

TEST(SurfaceEmbedding, RangesSplitTheWorkExactly) {
  const TetMesh mesh = box_mesh();
  const auto points = sample_points();
  const SurfaceEmbedding embedding(mesh, points);
  std::vector<Eigen::Vector3d> deformed = mesh.rest_positions_mm;
  std::mt19937 rng(9);
  std::normal_distribution<double> jitter(0.0, 0.3);
  for (auto& p : deformed) p += Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));

  std::vector<Eigen::Vector3d> whole(points.size()),
      halves(points.size(), Eigen::Vector3d::Constant(-1));
  embedding.update(deformed, whole);
  const int middle = embedding.vertex_count() / 2;
  embedding.update_range(middle, embedding.vertex_count(), deformed, halves);
  embedding.update_range(0, middle, deformed, halves);
  EXPECT_EQ(halves, whole);  // bit for bit: the same arithmetic per vertex

  std::vector<Eigen::Vector3d> untouched(points.size(), Eigen::Vector3d::Constant(-1));
  embedding.update_range(10, 20, deformed, untouched);
  EXPECT_EQ(untouched[9], Eigen::Vector3d::Constant(-1));
  EXPECT_EQ(untouched[20], Eigen::Vector3d::Constant(-1));
  EXPECT_EQ(untouched[15], whole[15]);
}

TEST(SurfaceEmbedding, RejectsMismatchedSizes) {
  const TetMesh mesh = box_mesh();
  const std::vector<Eigen::Vector3d> points{{0, 0, 6}, {1, 1, 6}};
  const SurfaceEmbedding embedding(mesh, points);
  std::vector<Eigen::Vector3d> out(2);
  EXPECT_THROW(embedding.update(std::vector<Eigen::Vector3d>(3), out), std::invalid_argument);
  EXPECT_THROW(embedding.update_range(1, 3, mesh.rest_positions_mm, out), std::invalid_argument);
  std::vector<Eigen::Vector3d> short_out(1);
  EXPECT_THROW(embedding.update(mesh.rest_positions_mm, short_out), std::invalid_argument);
  EXPECT_THROW(SurfaceEmbedding(TetMesh{}, points), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::geometry
