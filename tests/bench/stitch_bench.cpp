// Volume stitching at the published sizes (dissertation tables 5.1–5.3), per frame on 1 and 2
// threads, with the published sphere probe (radius 8 mm) pressed 4 mm into the middle of the
// region and sliding ±2 mm. Tissue at 2 mm spacing, fixed at its deepest face.
//   - Table 5.1: 25 × 12³ stitched (selective) against the one-piece 52 × 52 × 12 mesh;
//   - Tables 5.2/5.3: 1, 4, 9, 16, 25 sub-volumes of 12³ or 15³, with and without selective
//     simulation.
// Methods: the published PCG FEM (20 iterations) and MSDS (explicit Euler, 20 steps a frame),
// the implicit MSDS and the corotational FEM (20 iterations; stitched since 2026-11-27). Counters:
// sub-volumes stepped a frame, the largest frame (the target is every frame inside 16.7 ms at 25 ×
// 15³ on 2 threads), the seam gap. After the runs, a summary of medians with ratios: stitched over
// one piece (5.1), selective over all (5.2/5.3), and the coarse correction on over off (25
// sub-volumes, selective, 2 threads).
//   build/ci/tests/bench/stitch_bench [--benchmark_filter=...]

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "frame_time_reporter.hpp"
#include "stitch_scene.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"
#include "ultrasim/sim/engine_factory.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace {

using namespace ultrasim;

constexpr double kFrameDtS = 1.0 / 60.0;
constexpr int kWarmUpFrames = 20;  // the press, untimed

using bench::Region;

// side × side × depth nodes, built once per size (set-up is not what is timed).
const Region& region(int side, int depth) {
  static std::map<int, Region> regions;
  auto [it, inserted] = regions.try_emplace(side * 1000 + depth);
  if (inserted) it->second = bench::make_region(side, depth);
  return it->second;
}

// Pressed 4 mm over 20 frames at the region's middle, then sliding ±2 mm along x at 0.2 mm a
// frame.
sim::ProbeCollider probe_at(const Region& r, int frame) {
  const double middle = 0.5 * bench::kStitchSpacingMm * (r.grid.nodes.x() - 1);
  const double depth = std::min(4.0, 0.2 * frame);
  const int phase = std::max(0, frame - kWarmUpFrames) % 40;
  const double x = phase < 20 ? -2.0 + 0.2 * phase : 2.0 - 0.2 * (phase - 20);
  return bench::sphere_probe(middle + x, middle, depth);
}

sim::EngineKind method(benchmark::State& state) {
  return static_cast<sim::EngineKind>(state.range(0));
}

// Times each frame and sets the counters every benchmark reports.
template <typename Step>
void run_frames(benchmark::State& state, const Region& r, Step&& step) {
  for (int frame = 0; frame < kWarmUpFrames; ++frame) step(probe_at(r, frame));
  int frame = kWarmUpFrames;
  double max_ms = 0.0;
  for (auto _ : state) {
    const auto probe = probe_at(r, frame++);
    const auto start = std::chrono::steady_clock::now();
    step(probe);
    const std::chrono::duration<double, std::milli> took = std::chrono::steady_clock::now() - start;
    max_ms = std::max(max_ms, took.count());
  }
  state.counters["max_frame_ms"] = max_ms;
  state.counters["nodes"] = r.mesh.node_count();
  state.SetLabel(std::string(sim::engine_key(method(state))));
}

void BM_OnePiece(benchmark::State& state) {
  const Region& r = region(static_cast<int>(state.range(1)), static_cast<int>(state.range(2)));
  drivers::posix::ThreadPool jobs(static_cast<int>(state.range(3)));
  auto engine = sim::make_engine(method(state), r.mesh, r.materials, r.fixed, {}, {}, &jobs);
  run_frames(state, r, [&](const sim::ProbeCollider& p) { engine->step(&p, kFrameDtS); });
  state.counters["tets"] = r.mesh.tet_count();
}

// What the stitched frame adds to the seams: nothing, the coarse correction, or the fine one.
enum class Correction { kNone = 0, kCoarse = 1, kFine = 2 };
constexpr int kFineIterations = 20;  // as stitch_price's "fine"

void run_stitched(benchmark::State& state, int per_side, int sub_nodes, bool selective, int threads,
                  Correction correction) {
  const int side = per_side * sub_nodes - 2 * (per_side - 1);
  const Region& r = region(side, sub_nodes);
  drivers::posix::ThreadPool jobs(threads);
  sim::StitchingSettings stitching;
  stitching.sub_volumes = {per_side, per_side, 1};
  stitching.selective = selective;
  stitching.coarse_correction = correction == Correction::kCoarse;
  stitching.fine_correction_iterations = correction == Correction::kFine ? kFineIterations : 0;
  sim::StitchedVolume stitched(r.grid, r.materials, r.fixed, method(state), {}, stitching, &jobs);
  double stepped = 0.0, gap = 0.0;
  int frames = 0;
  run_frames(state, r, [&](const sim::ProbeCollider& p) {
    stitched.step(&p, kFrameDtS);
    stepped += stitched.last_stitch_stats().sub_volumes_stepped;
    gap = std::max(gap, stitched.last_stitch_stats().max_gap_mm);
    ++frames;
  });
  int tets = 0;
  for (int s = 0; s < stitched.sub_volume_count(); ++s) {
    const auto& b = stitched.box(s).nodes;
    tets += 5 * (b.x() - 1) * (b.y() - 1) * (b.z() - 1);
  }
  state.counters["stepped"] = stepped / frames;
  state.counters["max_gap_mm"] = gap;
  state.counters["tets"] = tets;
  state.counters["nodes"] = stitched.sub_volume_count() * sub_nodes * sub_nodes * sub_nodes;
}

void BM_Stitched(benchmark::State& state) {
  run_stitched(state, static_cast<int>(state.range(1)), static_cast<int>(state.range(2)),
               state.range(3) != 0, static_cast<int>(state.range(4)), Correction::kNone);
}

// The corrections' price: 25 sub-volumes, selective, 2 threads, without and with each.
void BM_StitchedCorrection(benchmark::State& state) {
  run_stitched(state, 5, static_cast<int>(state.range(1)), true, 2,
               static_cast<Correction>(state.range(2)));
}

constexpr int kMethods[] = {static_cast<int>(sim::EngineKind::kPcgFem),
                            static_cast<int>(sim::EngineKind::kCorotationalFem),
                            static_cast<int>(sim::EngineKind::kMsdsExplicit),
                            static_cast<int>(sim::EngineKind::kMsdsImplicit)};

void one_piece_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"method", "side", "depth", "threads"});
  for (int m : kMethods) {
    for (int threads : {1, 2}) b->Args({m, 52, 12, threads});
  }
}

void stitched_args(benchmark::internal::Benchmark* b) {
  b->ArgNames({"method", "per_side", "sub_nodes", "selective", "threads"});
  for (int m : kMethods) {
    for (int sub_nodes : {12, 15}) {
      for (int per_side = 1; per_side <= 5; ++per_side) {
        for (int selective : {0, 1}) {
          if (per_side == 1 && selective) continue;  // nothing to select
          for (int threads : {1, 2}) b->Args({m, per_side, sub_nodes, selective, threads});
        }
      }
    }
  }
}

BENCHMARK(BM_OnePiece)->Apply(one_piece_args)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK(BM_Stitched)->Apply(stitched_args)->Unit(benchmark::kMillisecond)->Iterations(60);
BENCHMARK(BM_StitchedCorrection)
    ->ArgNames({"method", "sub_nodes", "correction"})
    ->ArgsProduct({{kMethods[0], kMethods[1], kMethods[2], kMethods[3]}, {12, 15}, {0, 1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(60);

// The console output as usual, then the published tables' figures as medians and ratios.
class TableReporter : public bench::FrameTimeReporter {
 public:
  void print_summary() const {
    std::printf("\nTable 5.1: ms per frame, 25 x 12^3 stitched (selective) / one 52x52x12 mesh\n");
    std::printf("%-14s %8s %11s %11s %7s\n", "method", "threads", "one-piece", "stitched", "ratio");
    for (int m : kMethods) {
      for (int t : {1, 2}) {
        const double one = median_ms_by_prefix("BM_OnePiece/method:" + std::to_string(m) +
                                               "/side:52/depth:12/threads:" + std::to_string(t));
        const double st = median_ms_by_prefix(stitched_name(m, 5, 12, 1, t));
        if (one > 0.0 && st > 0.0) {
          std::printf("%-14s %8d %11.2f %11.2f %7.3f\n", key(m), t, one, st, st / one);
        }
      }
    }
    for (int sub_nodes : {12, 15}) {
      std::printf("\nTable 5.%d: ms per frame, n x %d^3, selective (all), 2 threads\n",
                  sub_nodes == 12 ? 2 : 3, sub_nodes);
      std::printf("%-14s", "method");
      for (int n = 1; n <= 5; ++n) std::printf(" %18d", n * n);
      std::printf("\n");
      for (int m : kMethods) {
        std::printf("%-14s", key(m));
        for (int n = 1; n <= 5; ++n) {
          const double all = median_ms_by_prefix(stitched_name(m, n, sub_nodes, 0, 2));
          const double sel =
              n == 1 ? all : median_ms_by_prefix(stitched_name(m, n, sub_nodes, 1, 2));
          std::printf(" %8.2f (%7.2f)", sel, all);
        }
        std::printf("\n");
      }
    }
    std::printf("\nCorrections: ms per frame, 25 x n^3, selective, 2 threads; ratios to none\n");
    std::printf("%-14s %9s %8s %8s %8s %7s %7s\n", "method", "sub_nodes", "none", "coarse", "fine",
                "coarse", "fine");
    for (int m : kMethods) {
      for (int sub_nodes : {12, 15}) {
        const auto name = [&](int correction) {
          return "BM_StitchedCorrection/method:" + std::to_string(m) +
                 "/sub_nodes:" + std::to_string(sub_nodes) +
                 "/correction:" + std::to_string(correction);
        };
        const double none = median_ms_by_prefix(name(0)), coarse = median_ms_by_prefix(name(1)),
                     fine = median_ms_by_prefix(name(2));
        if (none > 0.0 && coarse > 0.0 && fine > 0.0) {
          std::printf("%-14s %9d %8.2f %8.2f %8.2f %7.3f %7.3f\n", key(m), sub_nodes, none, coarse,
                      fine, coarse / none, fine / none);
        }
      }
    }
  }

 private:
  static const char* key(int m) { return sim::engine_key(static_cast<sim::EngineKind>(m)).data(); }
  static std::string stitched_name(int m, int n, int sub_nodes, int selective, int threads) {
    return "BM_Stitched/method:" + std::to_string(m) + "/per_side:" + std::to_string(n) +
           "/sub_nodes:" + std::to_string(sub_nodes) + "/selective:" + std::to_string(selective) +
           "/threads:" + std::to_string(threads);
  }
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  TableReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.print_summary();
  benchmark::Shutdown();
  return 0;
}
