// The deformed display surfaces against the embedding and normals worked out surface by surface:
// the per-frame update splits the vertices and triangles into chunks across surfaces, run on one
// thread or two, and must give the same floats.

#include "ultrasim/kiosk/display_surfaces.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "two_thread_jobs.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/geometry/triangle_mesh.hpp"
#include "ultrasim/hal/job_system.hpp"

namespace ultrasim::kiosk {
namespace {

// 40 × 40 × 30 mm at 0.5 mm: a vein ball of radius 12 mm (more vertices than one chunk holds)
// and a bone slab along the bottom.
imaging::Volume<std::uint8_t> vein_and_bone_labels() {
  imaging::Volume<std::uint8_t> labels({81, 81, 61}, Eigen::Vector3d::Constant(0.5),
                                       Eigen::Vector3d(-20, -20, 0));
  for (int k = 0; k < 61; ++k) {
    for (int j = 0; j < 81; ++j) {
      for (int i = 0; i < 81; ++i) {
        const Eigen::Vector3d p(-20 + 0.5 * i, -20 + 0.5 * j, 0.5 * k);
        std::uint8_t label = 3;  // muscle
        if ((p - Eigen::Vector3d(0, 0, 14)).norm() < 12.0) label = 4;
        if (p.z() > 27.0 && std::abs(p.x()) < 15.0) label = 7;
        labels.at(i, j, k) = label;
      }
    }
  }
  return labels;
}

TEST(DeformedSurfaces, MatchTheEmbeddingAndNormalsOfEachSurface) {
  const imaging::Volume<std::uint8_t> labels = vein_and_bone_labels();
  const geometry::TetMesh mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-20, -20, 0}, {20, 20, 30}, {9, 9, 7}));
  const std::vector<DisplaySurface> surfaces = build_display_surfaces(labels, mesh, 1.0);
  ASSERT_EQ(surfaces.size(), 2u);
  EXPECT_GT(surfaces[0].rest.vertices_mm.size(), 1024u) << "the vein must span several chunks";

  // A smooth press: every node moves, most by different amounts.
  std::vector<Eigen::Vector3d> deformed;
  for (const Eigen::Vector3d& p : mesh.rest_positions_mm) {
    const double dent = 3.0 * std::exp(-p.head<2>().squaredNorm() / 200.0) * (1.0 - p.z() / 30.0);
    deformed.push_back(p + Eigen::Vector3d(0.1 * std::sin(0.2 * p.y()), 0.05 * p.x(), dent));
  }
  DeformedSurfaces deformed_surfaces(surfaces);
  hal::InlineJobSystem inline_jobs;
  testing::TwoThreadJobs two_threads;
  for (hal::JobSystem* jobs :
       {static_cast<hal::JobSystem*>(&inline_jobs), static_cast<hal::JobSystem*>(&two_threads)}) {
    SCOPED_TRACE(jobs->thread_count());
    deformed_surfaces.update(deformed, *jobs);

    ASSERT_EQ(deformed_surfaces.views().size(), surfaces.size());
    for (std::size_t s = 0; s < surfaces.size(); ++s) {
      SCOPED_TRACE(surfaces[s].label);
      const std::size_t n = surfaces[s].rest.vertices_mm.size();
      std::vector<Eigen::Vector3d> positions(n), normals(n);
      surfaces[s].embedding.update(deformed, positions);
      geometry::compute_vertex_normals(positions, surfaces[s].rest.triangles, normals);
      const render::SurfaceView& view = deformed_surfaces.views()[s];
      ASSERT_EQ(view.positions_mm.size(), 3 * n);
      ASSERT_EQ(view.normals.size(), 3 * n);
      int moved = 0;
      for (std::size_t v = 0; v < n; ++v) {
        for (int a = 0; a < 3; ++a) {
          ASSERT_EQ(view.positions_mm[3 * v + a], static_cast<float>(positions[v][a])) << v;
          ASSERT_EQ(view.normals[3 * v + a], static_cast<float>(normals[v][a])) << v;
        }
        moved += (positions[v] - surfaces[s].rest.vertices_mm[v]).norm() > 1e-3;
      }
      EXPECT_GT(moved, static_cast<int>(n / 2)) << "the press must move the surface";
    }
  }
}

}  // namespace
}  // namespace ultrasim::kiosk
