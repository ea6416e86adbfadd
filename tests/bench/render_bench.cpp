// The kiosk screen at 1280×720 on this machine's GL (llvmpipe: rendering is CPU work here):
// draw alone (finished with glFinish), read-back alone, and both, with and without the embedded
// surfaces and with 4× MSAA. The synthetic scene is the one the render tests and render_demo use.
//   build/ci/tests/bench/render_bench --benchmark_counters_tabular=true

#include <GLES3/gl3.h>
#include <benchmark/benchmark.h>

#include "../unit/render/synthetic_scene.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/scene_renderer.hpp"

namespace {

using namespace ultrasim::render;

enum class Part { kDraw, kReadback, kDrawAndReadback };

// state.range(0): surface triangles (0: mesh, probe and B-scan only); range(1): MSAA samples.
void run(benchmark::State& state, Part part) {
  OffscreenOptions options;
  options.msaa_samples = static_cast<int>(state.range(1));
  OffscreenDisplay display(DisplaySettings{}, options);  // 1280 × 720
  SceneRenderer renderer(display);
  testing::SyntheticScene scene = testing::make_synthetic_scene();
  testing::add_synthetic_structures(scene, static_cast<int>(state.range(0)));
  RgbaImage image;
  const auto draw = [&] {
    display.begin_frame();
    renderer.draw(scene.frame);
    display.end_frame();
  };
  // Warm up: shader variants compiled, buffers and the image sized.
  draw();
  display.read_pixels_into(image);
  for (auto _ : state) {
    ++scene.frame.frame_index;
    switch (part) {
      case Part::kDraw:
        draw();
        glFinish();  // llvmpipe renders on worker threads: wait for them
        break;
      case Part::kReadback:
        display.read_pixels_into(image);
        break;
      case Part::kDrawAndReadback:
        draw();
        display.read_pixels_into(image);
        break;
    }
    benchmark::DoNotOptimize(image.rgba.data());
  }
  state.counters["fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_Draw(benchmark::State& state) {
  run(state, Part::kDraw);
}
void BM_Readback(benchmark::State& state) {
  run(state, Part::kReadback);
}
void BM_DrawAndReadback(benchmark::State& state) {
  run(state, Part::kDrawAndReadback);
}

void configurations(benchmark::internal::Benchmark* b) {
  b->ArgNames({"surface_tris", "msaa"});
  b->Args({0, 0})->Args({15000, 0})->Args({15000, 4});
  b->Unit(benchmark::kMillisecond)->UseRealTime();
}

BENCHMARK(BM_Draw)->Apply(configurations);
BENCHMARK(BM_Readback)
    ->Args({0, 0})
    ->ArgNames({"surface_tris", "msaa"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DrawAndReadback)->Apply(configurations);

}  // namespace

BENCHMARK_MAIN();
