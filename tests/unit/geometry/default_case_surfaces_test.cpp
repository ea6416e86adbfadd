// The vessel surfaces of the generated default case: the real input of the pipeline, with thin
// walls, structures running out through the volume's faces and labels touching each other.

#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>

#include "mesh_checks.hpp"
#include "ultrasim/geometry/marching_cubes.hpp"
#include "ultrasim/geometry/smoothing.hpp"
#include "ultrasim/geometry/surface_embedding.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/metaimage.hpp"

namespace ultrasim::geometry {
namespace {

struct Structure {
  const char* name;
  std::uint8_t label;
};

class DefaultCaseSurfaces : public ::testing::TestWithParam<Structure> {
 protected:
  static void SetUpTestSuite() {
    const auto path = std::filesystem::path(ULTRASIM_BINARY_DIR) / "cases/default/labels.mha";
    if (std::filesystem::exists(path))
      labels_ = new imaging::Volume<std::uint8_t>(imaging::read_volume_u8(path));
  }
  static void TearDownTestSuite() {
    delete labels_;
    labels_ = nullptr;
  }
  static LabelGridView view() {
    return {labels_->size(), labels_->spacing_mm(), labels_->origin_mm(), labels_->direction(),
            labels_->voxels()};
  }
  static imaging::Volume<std::uint8_t>* labels_;
};
imaging::Volume<std::uint8_t>* DefaultCaseSurfaces::labels_ = nullptr;

TEST_P(DefaultCaseSurfaces, ClosedManifoldThatTaubinKeepsAndTheMeshCarries) {
  if (labels_ == nullptr) GTEST_SKIP() << "build the ultrasim_default_case target first";
  const Structure structure = GetParam();
  TriangleMesh mesh = marching_cubes(view(), LabelSet{structure.label});
  ASSERT_GT(mesh.triangle_count(), 1000);
  expect_closed_manifold(mesh, structure.name);
  const double raw_volume = enclosed_volume_mm3(mesh);
  EXPECT_GT(raw_volume, 0.0);

  taubin_smooth(mesh, {});
  const double change = enclosed_volume_mm3(mesh) / raw_volume - 1.0;
  std::cout << structure.name << ": " << mesh.triangle_count() << " triangles, "
            << mesh.vertex_count() << " vertices, " << raw_volume << " mm3, Taubin changes it by "
            << 100 * change << " %\n";
  EXPECT_LT(std::abs(change), 0.02);
  EXPECT_TRUE(check_closed_oriented(mesh).closed_and_oriented());

  // The case's own simulation mesh (case.toml [mesh]): at rest the embedded surface is unchanged.
  const TetMesh tets = make_grid_tet_mesh(
      GridSpec::spanning(Eigen::Vector3d(-30, -20, 0), Eigen::Vector3d(30, 20, 45), {25, 9, 19}));
  const SurfaceEmbedding embedding(tets, mesh.vertices_mm);
  std::vector<Eigen::Vector3d> moved(mesh.vertices_mm.size());
  embedding.update(tets.rest_positions_mm, moved);
  double worst_mm = 0.0;
  for (std::size_t v = 0; v < moved.size(); ++v) {
    worst_mm = std::max(worst_mm, (moved[v] - mesh.vertices_mm[v]).norm());
  }
  EXPECT_LT(worst_mm, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Structures, DefaultCaseSurfaces,
                         ::testing::Values(Structure{"vein", 4}, Structure{"artery", 5},
                                           Structure{"nerve", 6}, Structure{"bone", 7}),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

}  // namespace
}  // namespace ultrasim::geometry
