// Every deformation method per frame at the published grid sizes, on 1 and 2 threads: a linear
// probe face pressed 4 mm into a soft block, sliding 0.5 mm a frame. Counters: the error of the
// displacement field against the exact FEM with the same (stick) contact after the same 60
// frames (max norm, relative), contact force and inverted tets. For the Pareto chart:
//   build/ci/tests/bench/engine_bench --benchmark_out=engines.csv --benchmark_out_format=csv
//   python3 scripts/plot_engines.py engines.csv docs/images/

#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/sim/engine_factory.hpp"

namespace {

using namespace ultrasim;

struct Block {
  geometry::TetMesh mesh;
  std::vector<sim::Material> materials;
  std::vector<std::uint8_t> fixed, skin;
};

// The default case's region, 60 × 40 × 45 mm, fixed at depth 45: fat over muscle.
const Block& block(int nx, int ny, int nz) {
  static std::map<long, Block> blocks;
  Block& b = blocks[(nx * 1000L + ny) * 1000L + nz];
  if (!b.mesh.tets.empty()) return b;
  b.mesh = geometry::make_grid_tet_mesh(
      geometry::GridSpec::spanning({-30, -20, 0}, {30, 20, 45}, {nx, ny, nz}));
  const auto& p = b.mesh.rest_positions_mm;
  for (const auto& t : b.mesh.tets) {
    const double z = (p[t[0]].z() + p[t[1]].z() + p[t[2]].z() + p[t[3]].z()) / 4;
    b.materials.push_back(z < 15 ? sim::Material{2, "fat", 20.0, 0.45}
                                 : sim::Material{3, "muscle", 50.0, 0.45});
  }
  b.fixed.assign(p.size(), 0);
  b.skin.assign(p.size(), 0);
  for (std::size_t n = 0; n < p.size(); ++n) {
    b.fixed[n] = p[n].z() == 45.0;
    b.skin[n] = p[n].z() == 0.0;
  }
  return b;
}

sim::ProbeCollider probe_at(int frame) {
  // 4 mm deep after a 20-frame press, then sliding ±5 mm at 0.5 mm a frame.
  const double depth = std::min(4.0, 0.2 * frame);
  const int phase = std::max(0, frame - 20) % 40;
  const double x = phase < 20 ? -5.0 + 0.5 * phase : 5.0 - 0.5 * (phase - 20);
  return sim::ProbeCollider::linear_face(Eigen::Vector3d(x, 0.3, depth),
                                         Eigen::Quaterniond::Identity(), 38.0, 10.0, 2.0);
}

void BM_Engine(benchmark::State& state) {
  const auto kind = static_cast<sim::EngineKind>(state.range(0));
  const Block& b = block(static_cast<int>(state.range(1)), static_cast<int>(state.range(2)),
                         static_cast<int>(state.range(3)));
  drivers::posix::ThreadPool jobs(static_cast<int>(state.range(4)));
  sim::EngineSettings settings;
  settings.exact.contact = sim::ContactModel::kStick;  // the same contact rule as the others
  auto engine = sim::make_engine(kind, b.mesh, b.materials, b.fixed, settings, b.skin, &jobs);
  auto reference = sim::make_engine(sim::EngineKind::kExactFem, b.mesh, b.materials, b.fixed,
                                    settings, b.skin, &jobs);
  // Accuracy first, untimed: the same 60 frames for both.
  sim::EngineStepStats stats;
  for (int frame = 0; frame < 60; ++frame) {
    const auto probe = probe_at(frame);
    stats = engine->step(&probe, 1.0 / 60.0);
    reference->step(&probe, 1.0 / 60.0);
  }
  const Eigen::VectorXd& want = reference->displacements_mm();
  const double error = (engine->displacements_mm() - want).lpNorm<Eigen::Infinity>() /
                       want.lpNorm<Eigen::Infinity>();
  int frame = 60;
  std::int64_t diverged = 0, frames = 0;
  for (auto _ : state) {
    const auto probe = probe_at(frame++);
    const auto s = engine->step(&probe, 1.0 / 60.0);
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
