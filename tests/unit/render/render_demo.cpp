// Writes a screenshot of the kiosk screen drawn from the synthetic scene (with its vein, artery,
// nerve and bone) and times draw + read-back per frame. Usage:
//   render_demo [out.png] [width height] [frames] [msaa_samples] [surface_triangles] [state]
// surface_triangles: about how many triangles the four structures have together (default 15000;
// 0 draws the scene without them). state: live (default), nocontact or frozen.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "synthetic_scene.hpp"
#include "ultrasim/render/offscreen_display.hpp"
#include "ultrasim/render/png_writer.hpp"
#include "ultrasim/render/scene_renderer.hpp"

int main(int argc, char** argv) {
  using namespace ultrasim::render;
  const std::string out = argc > 1 ? argv[1] : "render_demo.png";
  DisplaySettings settings;
  settings.width_px = argc > 3 ? std::atoi(argv[2]) : 1280;
  settings.height_px = argc > 3 ? std::atoi(argv[3]) : 720;
  const int frames = argc > 4 ? std::atoi(argv[4]) : 60;
  OffscreenOptions options;
  options.msaa_samples = argc > 5 ? std::atoi(argv[5]) : 0;
  const int surface_triangles = argc > 6 ? std::atoi(argv[6]) : 15000;

  OffscreenDisplay display(settings, options);
  SceneRenderer renderer(display);
  testing::SyntheticScene scene = testing::make_synthetic_scene();
  const std::string state = argc > 7 ? argv[7] : "live";
  scene.frame.bscan.in_contact = state != "nocontact";
  scene.frame.bscan.frozen = state == "frozen";
  testing::add_synthetic_structures(scene, surface_triangles);
  std::size_t triangles = 0;
  for (const SurfaceView& surface : scene.frame.surfaces) triangles += surface.triangles.size() / 3;
  RgbaImage image;

  const auto draw_once = [&] {
    display.begin_frame();
    renderer.draw(scene.frame);
    display.end_frame();
    display.read_pixels_into(image);
  };
  draw_once();
  write_png(out, image);

  std::vector<double> ms;
  for (int i = 0; i < frames; ++i) {
    scene.frame.frame_index = i;
    const auto t0 = std::chrono::steady_clock::now();
    draw_once();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  if (!ms.empty()) {
    std::printf(
        "%s %dx%d msaa=%d, %zu surface triangles: draw+readback median %.2f ms, p90 %.2f ms, "
        "min %.2f ms (%d frames)\n",
        display.renderer_name(), settings.width_px, settings.height_px, display.msaa_samples(),
        triangles, ms[ms.size() / 2], ms[ms.size() * 9 / 10], ms.front(), frames);
  }
  std::printf("wrote %s\n", out.c_str());
  return 0;
}
