#pragma once

namespace ultrasim::render {

enum class DisplayBackend {
  kOffscreen,  // surfaceless EGL into an FBO: tests, headless runs, screenshots
};

struct DisplaySettings {
  DisplayBackend backend = DisplayBackend::kOffscreen;
  int width_px = 1280;
  int height_px = 720;
};

}  // namespace ultrasim::render
