// The published explicit MSDS (20 forward-Euler steps of 5 ms a frame, masses scaled for that
// step) at the four published grid sizes: the engine on 1 and 2 threads against the naive
// reference step (tests/support/naive_msds.hpp: springs one by one in double) in the same run,
// on the engine benchmarks' scene (a linear probe face pressed 4 mm, then sliding). Before
// timing, each size checks that the engine and the reference agree over 60 frames.
//   build/ci/tests/bench/msds_bench --benchmark_repetitions=3

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "engine_scene.hpp"
#include "frame_time_reporter.hpp"
#include "naive_msds.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/msds.hpp"

namespace {

using namespace ultrasim;

constexpr int kSizes[][3] = {{20, 10, 10}, {24, 12, 12}, {28, 14, 14}, {32, 16, 16}};

const bench::Block& block_of(const benchmark::State& state) {
  return bench::block(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
                      static_cast<int>(state.range(2)));
}

sim::MsdsEngine make_engine(const bench::Block& b, hal::JobSystem* jobs) {
  return sim::MsdsEngine(sim::MsdsIntegrator::kExplicitEuler, b.mesh, b.materials, b.fixed,
                         sim::MsdsSettings{}, jobs);
}

// The reference with the engine's (scaled) masses: mass scaling is the engine's set-up, not
// what this benchmark compares.
testing::NaiveMsds make_reference(const bench::Block& b, const sim::MsdsEngine& engine) {
  testing::NaiveMsds reference(b.mesh, b.materials, b.fixed, sim::MsdsSettings{});
  reference.mass_kg.assign(engine.node_masses_kg().begin(), engine.node_masses_kg().end());
  return reference;
}

void reference_frame(testing::NaiveMsds& reference, const sim::ProbeCollider& probe) {
  const sim::MsdsSettings s;
  for (int i = 0; i < s.steps_per_frame; ++i) reference.step(s.time_step_s, &probe);
}

// Largest position difference over the largest displacement, after the same frames.
double relative_deviation(const bench::Block& b, const sim::MsdsEngine& engine,
                          const testing::NaiveMsds& reference) {
  double diff = 0.0, displacement = 0.0;
  for (int i = 0; i < engine.node_count(); ++i) {
    diff = std::max(diff, (engine.deformed_positions_mm()[i] - reference.x[i]).norm());
    displacement = std::max(displacement, (reference.x[i] - b.mesh.rest_positions_mm[i]).norm());
  }
  return diff / displacement;
}

void BM_NaiveReference(benchmark::State& state) {
  const bench::Block& b = block_of(state);
  const sim::MsdsEngine engine = make_engine(b, nullptr);
  testing::NaiveMsds reference = make_reference(b, engine);
  int frame = 0;
  for (auto _ : state) {
    reference_frame(reference, bench::probe_at(frame++));
    benchmark::DoNotOptimize(reference.x.data());
  }
}

void BM_Engine(benchmark::State& state) {
  const bench::Block& b = block_of(state);
  drivers::posix::ThreadPool jobs(static_cast<int>(state.range(3)));
  sim::MsdsEngine engine = make_engine(b, &jobs);
  int frame = 0;
  std::int64_t diverged = 0;
  for (auto _ : state) {
    const auto probe = bench::probe_at(frame++);
    diverged += engine.step(&probe, bench::kFrameDtS).diverged;
  }
  state.counters["diverged_frames"] = static_cast<double>(diverged);
}

void size_args(benchmark::internal::Benchmark* bench) {
  bench->ArgNames({"nx", "ny", "nz"});
  for (const auto& s : kSizes) bench->Args({s[0], s[1], s[2]});
}

void engine_args(benchmark::internal::Benchmark* bench) {
  bench->ArgNames({"nx", "ny", "nz", "threads"});
  for (const auto& s : kSizes) {
    for (int threads : {1, 2}) bench->Args({s[0], s[1], s[2], threads});
  }
}

BENCHMARK(BM_NaiveReference)->Apply(size_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Engine)->Apply(engine_args)->Unit(benchmark::kMillisecond)->UseRealTime();

// The console output as usual, then per size the engine's median wall time per frame as a ratio
// to the reference's of this run.
class RatioReporter : public bench::FrameTimeReporter {
 public:
  void print_summary() const {
    std::printf("\nms per frame (medians), engine as a ratio to the naive reference of this run\n");
    std::printf("%-10s %12s %12s %9s %12s %9s\n", "grid", "naive ms", "1 thread ms", "ratio",
                "2 threads ms", "ratio");
    for (const auto& s : kSizes) {
      const std::string size = "nx:" + std::to_string(s[0]) + "/ny:" + std::to_string(s[1]) +
                               "/nz:" + std::to_string(s[2]);
      const double naive = median_ms("BM_NaiveReference/" + size + "/real_time");
      const double one = median_ms("BM_Engine/" + size + "/threads:1/real_time");
      const double two = median_ms("BM_Engine/" + size + "/threads:2/real_time");
      if (naive <= 0.0 || one <= 0.0 || two <= 0.0) continue;
      std::printf("%2dx%2dx%2d   %12.2f %12.3f %9.4f %12.3f %9.4f\n", s[0], s[1], s[2], naive, one,
                  one / naive, two, two / naive);
    }
  }
};

// The times mean something only if both compute the same motion.
void check_agreement() {
  for (const auto& s : kSizes) {
    const bench::Block& b = bench::block(s[0], s[1], s[2]);
    sim::MsdsEngine engine = make_engine(b, nullptr);
    testing::NaiveMsds reference = make_reference(b, engine);
    for (int frame = 0; frame < bench::kAccuracyFrames; ++frame) {
      const auto probe = bench::probe_at(frame);
      engine.integrate_unchecked(&probe, sim::MsdsSettings{}.time_step_s,
                                 sim::MsdsSettings{}.steps_per_frame);
      reference_frame(reference, probe);
    }
    std::printf(
        "%dx%dx%d: engine vs naive reference after %d frames: %.2e of the largest "
        "displacement\n",
        s[0], s[1], s[2], bench::kAccuracyFrames, relative_deviation(b, engine, reference));
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  check_agreement();
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.print_summary();
  benchmark::Shutdown();
  return 0;
}
