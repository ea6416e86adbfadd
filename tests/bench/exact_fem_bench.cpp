// Exact quasi-static FEM (sim::ExactFem) per frame: a linear probe face sliding along the skin
// and pressing (frictionless contact, new contact nodes every frame) at the published grid sizes,
// on 1 and 2 threads. Set-up (factorisation and the skin's Green's functions) happens once per
// size outside the timed loop; its time is printed as a counter.
//   build/ci/tests/bench/exact_fem_bench --benchmark_repetitions=3
//   build/ci/tests/bench/exact_fem_bench --benchmark_filter=ContactRounds --benchmark_repetitions=3

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>

#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/exact_fem.hpp"

namespace {

using namespace ultrasim;

struct Problem {
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed, skin;
  std::unique_ptr<drivers::posix::ThreadPool> jobs;
  std::unique_ptr<sim::ExactFem> fem;
  double setup_ms = 0.0;
};

// The default case's region, 60 × 40 × 45 mm, fixed at depth 45, at the given node counts.
Problem& problem(int nx, int ny, int nz, int threads) {
  static std::map<long, Problem> problems;
  Problem& p = problems[((nx * 1000L + ny) * 1000L + nz) * 10 + threads];
  if (p.fem) return p;
  p.mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-30, -20, 0}, {30, 20, 45}, {nx, ny, nz}));
  p.materials.assign(p.mesh.tets.size(), sim::Material{1, "tissue", 30.0, 0.45});
  p.fixed.assign(p.mesh.rest_positions_mm.size(), 0);
  p.skin.assign(p.mesh.rest_positions_mm.size(), 0);
  for (int n = 0; n < p.mesh.node_count(); ++n) {
    p.fixed[n] = p.mesh.rest_positions_mm[n].z() == 45.0;
    p.skin[n] = p.mesh.rest_positions_mm[n].z() == 0.0;
  }
  p.jobs = std::make_unique<drivers::posix::ThreadPool>(threads);
  const auto start = std::chrono::steady_clock::now();
  p.fem = std::make_unique<sim::ExactFem>(p.mesh, p.materials, p.fixed, sim::ExactFemSettings{},
                                          p.skin, p.jobs.get());
  p.setup_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return p;
}

// A 38 × 10 mm linear face, 4 mm into the skin, sliding 0.5 mm a frame (30 mm/s at 60 Hz).
void BM_ExactFemSlidingLinearProbe(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                       static_cast<int>(state.range(2)), static_cast<int>(state.range(3)));
  double x = -10.0;
  std::int64_t contacts = 0, rounds = 0, frames = 0;
  for (auto _ : state) {
    x = x > 10.0 ? -10.0 : x + 0.5;
    const auto probe = sim::ProbeCollider::linear_face(
        Eigen::Vector3d(x, 0.3, 4.0), Eigen::Quaterniond::Identity(), 38.0, 10.0, 2.0);
    const auto stats = p.fem->step(&probe, 1.0 / 60.0);
    contacts += stats.contact_nodes;
    rounds += stats.iterations;
    ++frames;
  }
  state.counters["setup_ms"] = p.setup_ms;
  state.counters["contact_nodes"] = static_cast<double>(contacts) / frames;
  state.counters["rounds"] = static_cast<double>(rounds) / frames;
  state.counters["free_dofs"] = p.fem->free_dof_count();
}

BENCHMARK(BM_ExactFemSlidingLinearProbe)
    ->ArgNames({"nx", "ny", "nz", "threads"})
    ->Args({20, 10, 10, 1})
    ->Args({24, 12, 12, 1})
    ->Args({28, 14, 14, 1})
    ->Args({32, 16, 16, 1})
    ->Args({32, 16, 16, 2})
    ->Args({25, 9, 19, 1})
    ->Args({25, 9, 19, 2})
    ->Args({37, 9, 28, 1})  // the default case's mesh
    ->Args({37, 9, 28, 2})
    ->Unit(benchmark::kMillisecond);

// Frictionless contact rounds with and without the last frame's contact set (the mean frame
// time, the slowest frame, rounds a frame): a probe tilted 0.15 rad, 3 mm into the skin, sweeping
// ±5 mm and back every 4 s (slow at its ends, as a trainee's). carried = 0 is the reference: each
// frame forgets the last one's contacts (the field is set to itself, as a live switch does) and
// starts from the nodes on the probe, as every frame did before the set was carried over. One sweep
// untimed first: the Green's functions of the non-skin nodes the press holds are solved for and
// cached there.
void BM_ExactFemContactRounds(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                       static_cast<int>(state.range(2)), static_cast<int>(state.range(3)));
  const bool carried = state.range(4) != 0;
  constexpr int kSweepFrames = 240;
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitY()));
  int frame = 0;
  const auto step = [&] {
    const double x =
        5.0 * std::sin(2.0 * std::acos(-1.0) * (frame++ % kSweepFrames) / kSweepFrames);
    const auto probe =
        sim::ProbeCollider::linear_face(Eigen::Vector3d(x, 0.3, 3.0), tilt, 38.0, 10.0, 2.0);
    if (!carried) p.fem->set_displacements_mm(p.fem->displacements_mm());
    return p.fem->step(&probe, 1.0 / 60.0);
  };
  for (int i = 0; i < kSweepFrames; ++i) step();
  std::int64_t rounds = 0, frames = 0, most_rounds = 0;
  double slowest_ms = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const auto stats = step();
    slowest_ms =
        std::max(slowest_ms,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
    rounds += stats.iterations;
    most_rounds = std::max<std::int64_t>(most_rounds, stats.iterations);
    ++frames;
  }
  state.counters["rounds"] = static_cast<double>(rounds) / frames;
  state.counters["most_rounds"] = static_cast<double>(most_rounds);
  state.counters["slowest_ms"] = slowest_ms;
}

BENCHMARK(BM_ExactFemContactRounds)
    ->ArgNames({"nx", "ny", "nz", "threads", "carried"})
    ->Args({37, 9, 28, 2, 0})  // the default case's mesh
    ->Args({37, 9, 28, 2, 1})
    ->Iterations(480)
    ->Unit(benchmark::kMillisecond);

}  // namespace
BENCHMARK_MAIN();
