#include "ultrasim/geometry/marching_cubes.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include "mesh_checks.hpp"
#include "ultrasim/geometry/smoothing.hpp"

namespace ultrasim::geometry {
namespace {

// A label volume with its own storage; view() hands marching_cubes the plain grid view.
struct LabelGrid {
  Eigen::Vector3i size;
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();
  std::vector<std::uint8_t> labels;

  explicit LabelGrid(Eigen::Vector3i s) : size(s), labels(static_cast<std::size_t>(s.prod()), 0) {}
  std::uint8_t& at(int i, int j, int k) { return labels[i + size.x() * (j + size.y() * k)]; }
  Eigen::Vector3d world(int i, int j, int k) const {
    return origin_mm + direction * spacing_mm.cwiseProduct(Eigen::Vector3d(i, j, k));
  }
  void fill(const std::function<std::uint8_t(const Eigen::Vector3d&)>& label_at) {
    for (int k = 0; k < size.z(); ++k)
      for (int j = 0; j < size.y(); ++j)
        for (int i = 0; i < size.x(); ++i) at(i, j, k) = label_at(world(i, j, k));
  }
  LabelGridView view() const { return {size, spacing_mm, origin_mm, direction, labels}; }
};

TEST(MarchingCubes, SingleVoxelIsAnOutwardOctahedron) {
  LabelGrid grid({3, 3, 3});
  grid.at(1, 1, 1) = 4;
  const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{4});
  EXPECT_EQ(mesh.vertex_count(), 6);
  EXPECT_EQ(mesh.triangle_count(), 8);
  expect_closed_manifold(mesh, "single voxel");
  // Vertices half a voxel from the centre along each axis: volume 4/3 · 0.5³.
  EXPECT_NEAR(enclosed_volume_mm3(mesh), 4.0 / 3.0 * 0.125, 1e-12);
}

TEST(MarchingCubes, EmptySetGivesEmptyMesh) {
  LabelGrid grid({4, 4, 4});
  grid.at(1, 2, 3) = 3;
  const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{4});
  EXPECT_EQ(mesh.vertex_count(), 0);
  EXPECT_EQ(mesh.triangle_count(), 0);
}

TEST(MarchingCubes, RejectsLabelsOfTheWrongSize) {
  LabelGrid grid({4, 4, 4});
  LabelGridView view = grid.view();
  view.labels = view.labels.first(10);
  EXPECT_THROW(marching_cubes(view, LabelSet{1}), std::invalid_argument);
}

// All 256 corner configurations of one cube, each alone in a 2×2×2 grid (its surface also closes
// over the grid border, so every face of every case is exercised from both sides).
TEST(MarchingCubes, EveryCubeConfigurationIsClosedAndOutward) {
  for (int config = 1; config < 256; ++config) {
    LabelGrid grid({2, 2, 2});
    for (int c = 0; c < 8; ++c) grid.at(c & 1, (c >> 1) & 1, c >> 2) = (config >> c) & 1;
    const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{1});
    expect_closed_manifold(mesh, "config " + std::to_string(config));
    EXPECT_GT(enclosed_volume_mm3(mesh), 0.0) << config;
  }
}

// Random labels make every ambiguous face and cube case occur many times, in every combination
// with its neighbours.
TEST(MarchingCubes, RandomVolumesAreClosedManifolds) {
  std::mt19937 rng(3);
  for (const double fraction : {0.2, 0.5, 0.8}) {
    std::bernoulli_distribution inside(fraction);
    LabelGrid grid({17, 13, 11});
    for (auto& l : grid.labels) l = inside(rng) ? 5 : 2;
    MarchingCubesStats stats;
    const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{5}, &stats);
    expect_closed_manifold(mesh, "fraction " + std::to_string(fraction));
    EXPECT_GT(enclosed_volume_mm3(mesh), 0.0);
    EXPECT_GT(stats.cubes_cut, 0);
    // Triangle count and vertex count of a closed surface: 3F = 2E.
    EXPECT_EQ(euler_characteristic(mesh) % 2, 0);
  }
}

TEST(MarchingCubes, SurfaceTouchingTheBorderIsClosedThere) {
  LabelGrid grid({6, 5, 4});
  std::fill(grid.labels.begin(), grid.labels.end(), 7);
  const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{7});
  expect_closed_manifold(mesh, "full grid");
  EXPECT_EQ(euler_characteristic(mesh), 2);  // one sphere-like surface
  // The box of voxel centres grown by half a voxel, minus the cut-off edges and corners.
  EXPECT_LT(enclosed_volume_mm3(mesh), 6.0 * 5.0 * 4.0);
  EXPECT_GT(enclosed_volume_mm3(mesh), 5.0 * 4.0 * 3.0);
}

TEST(MarchingCubes, LabelSetSelectsSeveralLabels) {
  LabelGrid grid({5, 3, 3});
  grid.at(1, 1, 1) = 4;
  grid.at(2, 1, 1) = 5;
  grid.at(3, 1, 1) = 6;
  const TriangleMesh joined = marching_cubes(grid.view(), LabelSet{4, 5});
  expect_closed_manifold(joined, "two labels");
  EXPECT_EQ(euler_characteristic(joined), 2);
  const TriangleMesh one = marching_cubes(grid.view(), LabelSet{4});
  EXPECT_GT(enclosed_volume_mm3(joined), 1.5 * enclosed_volume_mm3(one));
}

// Diagonal neighbours are separate objects (6-connectivity of the inside), as the face rule says.
TEST(MarchingCubes, DiagonalNeighboursStaySeparate) {
  LabelGrid grid({4, 4, 4});
  grid.at(1, 1, 1) = 1;
  grid.at(2, 2, 1) = 1;  // each pair shares an edge, none shares a face
  grid.at(1, 2, 2) = 1;
  const TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{1});
  expect_closed_manifold(mesh, "diagonal voxels");
  EXPECT_EQ(euler_characteristic(mesh), 6);  // three separate spheres
  EXPECT_NEAR(enclosed_volume_mm3(mesh), 3 * 4.0 / 3.0 * 0.125, 1e-12);
}

TEST(MarchingCubes, SphereMatchesAnalyticVolumeAndAreaAfterSmoothing) {
  const double radius_mm = 6.0;
  LabelGrid grid({35, 35, 35});
  grid.spacing_mm = Eigen::Vector3d::Constant(0.5);
  grid.origin_mm = Eigen::Vector3d::Constant(-8.5);
  grid.fill([&](const Eigen::Vector3d& p) { return p.norm() <= radius_mm ? 4 : 2; });
  TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{4});
  expect_closed_manifold(mesh, "sphere");
  EXPECT_EQ(euler_characteristic(mesh), 2);

  const double volume = 4.0 / 3.0 * std::numbers::pi * std::pow(radius_mm, 3);
  const double area = 4.0 * std::numbers::pi * radius_mm * radius_mm;
  const double raw_volume = enclosed_volume_mm3(mesh), raw_area = surface_area_mm2(mesh);
  taubin_smooth(mesh, {});
  const double smooth_volume = enclosed_volume_mm3(mesh), smooth_area = surface_area_mm2(mesh);
  RecordProperty("raw_volume_error_pct", std::to_string(100 * (raw_volume / volume - 1)));
  RecordProperty("raw_area_error_pct", std::to_string(100 * (raw_area / area - 1)));
  RecordProperty("taubin_volume_error_pct", std::to_string(100 * (smooth_volume / volume - 1)));
  RecordProperty("taubin_area_error_pct", std::to_string(100 * (smooth_area / area - 1)));
  EXPECT_NEAR(smooth_volume / volume, 1.0, 0.03);
  EXPECT_NEAR(smooth_area / area, 1.0, 0.03);
  expect_closed_manifold(mesh, "smoothed sphere");  // smoothing never changes topology
  // Every vertex ends near the sphere: within a quarter voxel.
  for (const auto& v : mesh.vertices_mm) EXPECT_NEAR(v.norm(), radius_mm, 0.125);
}

// Anisotropic spacing and a rotated, mirrored direction matrix: the surface still faces outward
// and lands where the world-space ellipsoid is.
TEST(MarchingCubes, EllipsoidInARotatedMirroredGrid) {
  const Eigen::Vector3d semi_axes_mm(7.0, 4.0, 5.0);
  const Eigen::Vector3d centre_mm(10.0, -3.0, 20.0);
  LabelGrid grid({70, 56, 36});  // holds the ellipsoid whatever the rotation
  grid.spacing_mm = Eigen::Vector3d(0.3, 0.3, 0.45);
  grid.direction =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() *
      Eigen::Vector3d(1, -1, 1).asDiagonal();
  ASSERT_LT(grid.direction.determinant(), 0);
  // Put the grid's centre on the ellipsoid's centre.
  const Eigen::Vector3d half_extent =
      grid.spacing_mm.cwiseProduct((grid.size.array() - 1).cast<double>().matrix()) / 2;
  grid.origin_mm = centre_mm - grid.direction * half_extent;
  grid.fill([&](const Eigen::Vector3d& p) {
    return (p - centre_mm).cwiseQuotient(semi_axes_mm).norm() <= 1.0 ? 5 : 3;
  });
  TriangleMesh mesh = marching_cubes(grid.view(), LabelSet{5});
  expect_closed_manifold(mesh, "ellipsoid");
  taubin_smooth(mesh, {});
  const double volume = 4.0 / 3.0 * std::numbers::pi * semi_axes_mm.prod();
  EXPECT_NEAR(enclosed_volume_mm3(mesh) / volume, 1.0, 0.03);
  // Knud Thomsen's approximation of an ellipsoid's area (within ~1 %).
  const double p = 1.6075;
  const double a = semi_axes_mm.x(), b = semi_axes_mm.y(), c = semi_axes_mm.z();
  const double area =
      4 * std::numbers::pi *
      std::pow((std::pow(a * b, p) + std::pow(a * c, p) + std::pow(b * c, p)) / 3, 1 / p);
  EXPECT_NEAR(surface_area_mm2(mesh) / area, 1.0, 0.03);
  for (const auto& v : mesh.vertices_mm) {
    EXPECT_NEAR((v - centre_mm).cwiseQuotient(semi_axes_mm).norm(), 1.0, 0.06);
  }
}

}  // namespace
}  // namespace ultrasim::geometry
