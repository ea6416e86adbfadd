#include "ultrasim/geometry/smoothing.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "ultrasim/geometry/marching_cubes.hpp"

namespace ultrasim::geometry {
namespace {

// The marching-cubes surface of a voxelised sphere, the staircase that smoothing is for.
TriangleMesh voxel_sphere(double radius_mm, double voxel_mm = 0.5) {
  const int n = static_cast<int>(std::ceil(2 * radius_mm / voxel_mm)) + 5;
  const double origin = -voxel_mm * (n - 1) / 2.0;
  std::vector<std::uint8_t> labels(static_cast<std::size_t>(n) * n * n);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p =
            Eigen::Vector3d::Constant(origin) + voxel_mm * Eigen::Vector3d(i, j, k);
        labels[i + n * (j + n * k)] = p.norm() <= radius_mm ? 1 : 0;
      }
  const LabelGridView view{Eigen::Vector3i::Constant(n), Eigen::Vector3d::Constant(voxel_mm),
                           Eigen::Vector3d::Constant(origin), Eigen::Matrix3d::Identity(), labels};
  return marching_cubes(view, LabelSet{1});
}

struct VolumeChanges {
  double taubin = 0.0;     // relative to the marching-cubes volume
  double laplacian = 0.0;  // relative to the marching-cubes volume
  double taubin_vs_sphere = 0.0;
};

VolumeChanges smooth_100_iterations(double radius_mm, double voxel_mm) {
  const double analytic = 4.0 / 3.0 * std::numbers::pi * std::pow(radius_mm, 3);
  const TriangleMesh raw = voxel_sphere(radius_mm, voxel_mm);
  const double raw_volume = enclosed_volume_mm3(raw);
  TriangleMesh taubin = raw;
  taubin_smooth(taubin, TaubinSettings{0.5, -0.53, 100});
  TriangleMesh laplacian = raw;
  laplacian_smooth(laplacian, 0.5, 100);
  const VolumeChanges changes{enclosed_volume_mm3(taubin) / raw_volume - 1.0,
                              enclosed_volume_mm3(laplacian) / raw_volume - 1.0,
                              enclosed_volume_mm3(taubin) / analytic - 1.0};
  std::cout << "sphere of " << radius_mm / voxel_mm << " voxels radius, volume change after 100 "
            << "iterations: taubin " << 100 * changes.taubin << " % ("
            << 100 * changes.taubin_vs_sphere << " % vs the true sphere), laplacian "
            << 100 * changes.laplacian << " %\n";
  return changes;
}

// Issue 4: Taubin's λ|μ keeps the enclosed volume within 2 % after 100 iterations while the
// published Gaussian (Laplacian) smoothing, same λ and iteration count, loses more. The sphere is
// the artery's size at the default case's resolution (radius 5 mm, 0.25 mm voxels).
TEST(Smoothing, TaubinKeepsVolumeWhereLaplacianShrinks) {
  const VolumeChanges changes = smooth_100_iterations(5.0, 0.25);
  RecordProperty("taubin_volume_change_pct", std::to_string(100 * changes.taubin));
  RecordProperty("laplacian_volume_change_pct", std::to_string(100 * changes.laplacian));
  EXPECT_LT(std::abs(changes.taubin), 0.02);
  EXPECT_LT(std::abs(changes.taubin_vs_sphere), 0.02);
  EXPECT_LT(changes.laplacian, -0.02);
  EXPECT_GT(std::abs(changes.laplacian), 5 * std::abs(changes.taubin));
}

// The limit of λ = 0.5, μ = −0.53: frequencies below the pass-band gain about (|μ| − λ)·k per
// iteration, and a small object's overall size is such a frequency, with k growing as 1/radius².
// A sphere 6 voxels in radius grows ~10 % in 100 iterations (Laplacian loses ~80 %), so structures
// that thin want fewer iterations or μ nearer −λ. Pinned here so a change in the filter shows.
TEST(Smoothing, SmallStructuresInflateSlowlyUnderTaubin) {
  const VolumeChanges changes = smooth_100_iterations(3.0, 0.5);
  EXPECT_GT(changes.taubin, 0.02);
  EXPECT_LT(changes.taubin, 0.12);
  EXPECT_LT(changes.laplacian, -0.5);
  // μ nearer −λ (pass-band k_PB = 0.02 instead of 0.113) keeps even this one within 2 %.
  const TriangleMesh raw = voxel_sphere(3.0, 0.5);
  TriangleMesh gentler = raw;
  taubin_smooth(gentler, TaubinSettings{0.5, -0.505, 100});
  EXPECT_NEAR(enclosed_volume_mm3(gentler) / enclosed_volume_mm3(raw), 1.0, 0.02);
}

TEST(Smoothing, TaubinFlattensTheStaircaseOntoTheSphere) {
  const double radius_mm = 6.0;
  TriangleMesh mesh = voxel_sphere(radius_mm);
  const auto spread = [&] {
    double worst = 0.0;
    for (const auto& v : mesh.vertices_mm) worst = std::max(worst, std::abs(v.norm() - radius_mm));
    return worst;
  };
  const double before = spread();
  taubin_smooth(mesh, {});
  EXPECT_LT(spread(), before / 2);
}

TEST(Smoothing, ZeroIterationsChangeNothing) {
  TriangleMesh mesh = voxel_sphere(2.0);
  const auto before = mesh.vertices_mm;
  taubin_smooth(mesh, TaubinSettings{0.5, -0.53, 0});
  laplacian_smooth(mesh, 0.5, 0);
  EXPECT_EQ(mesh.vertices_mm, before);
}

TEST(Smoothing, TranslationCommutesWithSmoothing) {
  TriangleMesh a = voxel_sphere(3.0);
  TriangleMesh b = a;
  const Eigen::Vector3d shift(12.5, -4.0, 7.25);
  for (auto& v : b.vertices_mm) v += shift;
  taubin_smooth(a, TaubinSettings{0.5, -0.53, 10});
  taubin_smooth(b, TaubinSettings{0.5, -0.53, 10});
  for (int v = 0; v < a.vertex_count(); ++v) {
    EXPECT_LT((a.vertices_mm[v] + shift - b.vertices_mm[v]).norm(), 1e-9);
  }
}

TEST(Smoothing, UnusedVertexStaysPut) {
  TriangleMesh mesh = voxel_sphere(2.0);
  mesh.vertices_mm.emplace_back(100, 100, 100);
  taubin_smooth(mesh, {});
  EXPECT_EQ(mesh.vertices_mm.back(), Eigen::Vector3d(100, 100, 100));
}

TEST(Smoothing, RejectsBadWeightsAndSizes) {
  TriangleMesh mesh = voxel_sphere(2.0);
  EXPECT_THROW(taubin_smooth(mesh, TaubinSettings{0.5, -0.4, 1}), std::invalid_argument);
  EXPECT_THROW(taubin_smooth(mesh, TaubinSettings{0.0, -0.53, 1}), std::invalid_argument);
  EXPECT_THROW(laplacian_smooth(mesh, 1.5, 1), std::invalid_argument);
  SurfaceSmoother smoother(mesh.vertex_count(), mesh.triangles);
  std::vector<Eigen::Vector3d> too_few(3);
  EXPECT_THROW(smoother.step(too_few, 0.5), std::invalid_argument);
  const std::vector<Triangle> bad{{0, 1, 7}};
  EXPECT_THROW(SurfaceSmoother(3, bad), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::geometry
