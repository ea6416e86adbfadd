// Every deformation method per frame at the published grid sizes, on 1 and 2 threads: a linear
// probe face pressed 4 mm into a soft block, sliding 0.5 mm a frame. Counters: the error of the
// displacement field against the exact FEM with the same (stick) contact after the same 60
// frames (max norm, relative), contact force and inverted tets. For the Pareto chart:
//   build/ci/tests/bench/engine_bench --benchmark_out=engines.csv --benchmark_out_format=csv
//   /usr/bin/python3 scripts/plot_engines.py --bench engines.csv --out docs/images

#include <benchmark/benchmark.h>

#include <string>

#include "engine_scene.hpp"
#include "engine_settings.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/engine_factory.hpp"

namespace {

using namespace ultrasim;
using bench::Block;
using bench::block;
using bench::probe_at;

void BM_Engine(benchmark::State& state) {
  const auto kind = static_cast<sim::EngineKind>(state.range(0));
  const Block& b = block(static_cast<int>(state.range(1)), static_cast<int>(state.range(2)),
                         static_cast<int>(state.range(3)));
  drivers::posix::ThreadPool jobs(static_cast<int>(state.range(4)));
  // The published stick contact, for every method alike.
  sim::EngineSettings settings = testing::stick_contact();
  settings.exact.contact = sim::ContactModel::kStick;
  auto engine = sim::make_engine(kind, b.mesh, b.materials, b.fixed, settings, b.skin, &jobs);
  auto reference = sim::make_engine(sim::EngineKind::kExactFem, b.mesh, b.materials, b.fixed,
                                    settings, b.skin, &jobs);
  // Accuracy first, untimed: the same frames for both.
  sim::EngineStepStats stats;
  for (int frame = 0; frame < bench::kAccuracyFrames; ++frame) {
    const auto probe = probe_at(frame);
    stats = engine->step(&probe, bench::kFrameDtS);
    reference->step(&probe, bench::kFrameDtS);
  }
  const double error =
      bench::relative_max_error(engine->displacements_mm(), reference->displacements_mm());
  int frame = bench::kAccuracyFrames;
  std::int64_t diverged = 0, frames = 0;
  for (auto _ : state) {
    const auto probe = probe_at(frame++);
    const auto s = engine->step(&probe, bench::kFrameDtS);
    diverged += s.diverged;
    ++frames;
  }
  state.SetLabel(std::string(sim::engine_key(kind)));
  state.counters["error_vs_exact"] = error;
  state.counters["contact_force_n"] = stats.contact_force_n;
  state.counters["diverged_frames"] = static_cast<double>(diverged) / frames;
  state.counters["nodes"] = b.mesh.node_count();
}

void engine_args(benchmark::internal::Benchmark* bench) {
  bench->ArgNames({"method", "nx", "ny", "nz", "threads"});
  const int sizes[][3] = {{20, 10, 10}, {24, 12, 12}, {28, 14, 14}, {32, 16, 16}};
  for (int method = 0; method < 5; ++method) {
    for (const auto& s : sizes) {
      for (int threads : {1, 2}) bench->Args({method, s[0], s[1], s[2], threads});
    }
  }
}

BENCHMARK(BM_Engine)->Apply(engine_args)->Unit(benchmark::kMillisecond)->MinTime(0.5);

}  // namespace

BENCHMARK_MAIN();
