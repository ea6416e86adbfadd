// The kiosk screen at 1280×720 on this machine's GL (llvmpipe: rendering is CPU work here):
// draw alone (finished with glFinish), read-back alone, and both, with and without the embedded
// surfaces and with 4× MSAA. The synthetic scene is the one the render tests and render_demo use.
//   build/ci/tests/bench/render_bench --benchmark_counters_tabular=true

#include <GLES3/gl3.h>
#include <benchmark/benchmark.h>

#include "../unit/render/synthetic_scene.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/scene_renderer.hpp"
#include "ultrasim/render/trainer_ui.hpp"

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

// What the trainer's screen adds and what the trainee's toggles save, against the plain draw in
// the same run: range(0) the controls (render::TrainerUi) drawn over the scene, range(1) the
// mesh's wireframe shown (with 15,000 surface triangles).
void BM_DrawParts(benchmark::State& state) {
  OffscreenDisplay display(DisplaySettings{});  // 1280 × 720
  SceneRenderer renderer(display);
  TrainerUi ui(display);
  testing::SyntheticScene scene = testing::make_synthetic_scene();
  testing::add_synthetic_structures(scene, 15000);
  const bool controls = state.range(0) != 0;
  scene.frame.view.show_mesh = state.range(1) != 0;
  const float tgc[8] = {};
  const std::string_view names[] = {"default-upper-arm"};
  TrainerModel model;
  model.tgc_db = tgc;
  model.case_names = names;
  model.method_names = names;
  const auto draw = [&] {
    display.begin_frame();
    renderer.draw(scene.frame);
    if (controls) benchmark::DoNotOptimize(ui.frame(scene.frame, renderer.layout(), model, {}));
    display.end_frame();
  };
  draw();
  for (auto _ : state) {
    ++scene.frame.frame_index;
    draw();
    glFinish();
  }
  state.counters["fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK(BM_Draw)->Apply(configurations);
BENCHMARK(BM_DrawParts)
    ->ArgNames({"controls", "mesh"})
    ->Args({0, 1})
    ->Args({1, 1})
    ->Args({1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Readback)
    ->Args({0, 0})
    ->ArgNames({"surface_tris", "msaa"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DrawAndReadback)->Apply(configurations);

}  // namespace

BENCHMARK_MAIN();
