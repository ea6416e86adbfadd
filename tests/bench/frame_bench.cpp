// One frame's work at the published 32×16×16 grid (8,192 nodes, 34,875 tets): the FEM step with
// the published budget of 20 PCG iterations, and the per-pixel reference B-scan (512×512) through
// the deformed mesh beside plain undeformed slicing of the same plane.
//   build/ci/tests/bench/frame_bench --benchmark_counters_tabular=true

#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "engine_settings.hpp"
#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/bscan.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace {

using namespace ultrasim;

struct Scene {
  geometry::TetMesh mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-30, -15, 0}, {30, 15, 30}, {32, 16, 16}));
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed;
  imaging::Volume<std::uint8_t> volume{{241, 121, 121}, {0.25, 0.25, 0.25}, {-30, -15, 0}};

  Scene() {
    materials.assign(mesh.tets.size(), sim::Material{3, "muscle", 50.0, 0.45});
    fixed.assign(mesh.rest_positions_mm.size(), 0);
    for (int n = 0; n < mesh.node_count(); ++n) fixed[n] = mesh.rest_positions_mm[n].z() == 30.0;
    auto voxels = volume.voxels();
    for (std::size_t i = 0; i < voxels.size(); ++i)
      voxels[i] = static_cast<std::uint8_t>(i * 2654435761u >> 24);
  }
};

using testing::pcg_settings;

Scene& scene() {
  static Scene s;
  return s;
}

void BM_FemStep20Iterations(benchmark::State& state) {
  auto& s = scene();
  sim::LinearFem fem(s.mesh, s.materials, s.fixed, pcg_settings(20, 1e-12));
  double depth = 0.0;
  for (auto _ : state) {
    depth = std::fmod(depth + 0.05, 6.0);
    benchmark::DoNotOptimize(
        fem.step(sim::SphereCollider::behind_face({0, 0, depth}, {0, 0, 1}, 30)));
  }
  state.counters["dofs"] = 3.0 * s.mesh.node_count();
}
BENCHMARK(BM_FemStep20Iterations)->Unit(benchmark::kMillisecond);

void slice(benchmark::State& state, bool deformed) {
  auto& s = scene();
  sim::LinearFem fem(s.mesh, s.materials, s.fixed, pcg_settings(500, 1e-8));
  fem.step(sim::SphereCollider::behind_face({0, 0, 5}, {0, 0, 1}, 30));
  geometry::TetLocator locator(s.mesh);
  imaging::ProbeGeometry probe;
  const imaging::BscanGrid grid(probe, 512, 512);
  imaging::ProbePose pose;
  pose.face_center_mm = {0, 0, 5};
  std::vector<std::uint8_t> image(512 * 512);
  for (auto _ : state) {
    if (deformed) {
      locator.rebuild(fem.deformed_positions_mm());
      imaging::slice_deformed_reference(s.volume, s.mesh, locator, pose, grid, {}, image);
    } else {
      imaging::slice_undeformed(s.volume, pose, grid, {}, image);
    }
    benchmark::DoNotOptimize(image.data());
  }
}
void BM_BscanUndeformed512(benchmark::State& state) {
  slice(state, false);
}
void BM_BscanDeformedPerPixelReference512(benchmark::State& state) {
  slice(state, true);
}
BENCHMARK(BM_BscanUndeformed512)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BscanDeformedPerPixelReference512)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
