// Exact quasi-static FEM (sim::ExactFem) per frame at two grid sizes: a probe sliding along the
// skin (new contact nodes every frame, so new K⁻¹ columns) against one held still (all columns
// cached). The factorisation happens once per size, outside the timed loop; its time is printed
// as a counter.
//   build/ci/tests/bench/exact_fem_bench --benchmark_repetitions=3

#include <benchmark/benchmark.h>

#include <chrono>
#include <map>
#include <memory>

#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace {

using namespace ultrasim;

struct Problem {
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed;
  std::unique_ptr<sim::ExactFem> fem;
  double factor_ms = 0.0;
};

// A soft block 80 × 40 × 40 mm fixed at depth 40, at the given node counts; built once per size.
Problem& problem(int nx, int ny, int nz) {
  static std::map<int, Problem> problems;
  Problem& p = problems[nx * 1'000'000 + ny * 1'000 + nz];
  if (p.fem) return p;
  p.mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-40, -20, 0}, {40, 20, 40}, {nx, ny, nz}));
  p.materials.assign(p.mesh.tets.size(), sim::Material{1, "tissue", 30.0, 0.45});
  p.fixed.assign(p.mesh.rest_positions_mm.size(), 0);
  for (int n = 0; n < p.mesh.node_count(); ++n)
    p.fixed[n] = p.mesh.rest_positions_mm[n].z() == 40.0;
  const auto start = std::chrono::steady_clock::now();
  p.fem = std::make_unique<sim::ExactFem>(p.mesh, p.materials, p.fixed);
  p.factor_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return p;
}

void BM_ExactFemSlidingProbe(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                       static_cast<int>(state.range(2)));
  double x = -20.0;
  std::int64_t new_columns = 0, frames = 0;
  for (auto _ : state) {
    x = x > 20.0 ? -20.0 : x + 2.0;  // 2 mm a frame: new skin nodes come into contact
    const auto stats = p.fem->step(sim::SphereCollider{Eigen::Vector3d(x, 0.3, -27.0), 30.0});
    new_columns += stats.columns_computed;
    ++frames;
  }
  state.counters["factor_ms"] = p.factor_ms;
  state.counters["new_columns_per_frame"] = static_cast<double>(new_columns) / frames;
  state.counters["free_dofs"] = p.fem->free_dof_count();
}

void BM_ExactFemProbeHeldStill(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                       static_cast<int>(state.range(2)));
  const sim::SphereCollider still{Eigen::Vector3d(0.0, 0.3, -27.0), 30.0};
  p.fem->step(still);
  for (auto _ : state) benchmark::DoNotOptimize(p.fem->step(still));
  state.counters["factor_ms"] = p.factor_ms;
}

BENCHMARK(BM_ExactFemSlidingProbe)
    ->Args({25, 9, 19})
    ->Args({32, 16, 16})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ExactFemProbeHeldStill)
    ->Args({25, 9, 19})
    ->Args({32, 16, 16})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
