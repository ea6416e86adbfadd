#pragma once

#include <string>

namespace ultrasim::render {

enum class DisplayBackend {
  kOffscreen,  // surfaceless EGL into an FBO: tests, headless runs, screenshots
  kKms,        // the dedicated display: DRM/KMS page flips (KmsDisplay)
};

struct DisplaySettings {
  DisplayBackend backend = DisplayBackend::kOffscreen;
  int width_px = 1280;  // offscreen only: a KMS display takes its mode's size
  int height_px = 720;
  // kms: the device, the output (empty: the first connected one) and its mode (0 × 0: the
  // display's preferred mode; refresh 0: the fastest at that size); legacy modeset and page
  // flips even where atomic commits work.
  std::string kms_device = "/dev/dri/card0";
  std::string kms_connector;
  int kms_mode_width_px = 0;
  int kms_mode_height_px = 0;
  int kms_refresh_hz = 0;
  bool kms_legacy = false;
  // The trainer's touch screen or mouse (an evdev node, /dev/input/eventN); empty: none.
  std::string pointer_device;
};

// An offscreen display of the given size (tests, tools, screenshots).
inline DisplaySettings offscreen_display_settings(int width_px, int height_px) {
  DisplaySettings s;
  s.width_px = width_px;
  s.height_px = height_px;
  return s;
}

}  // namespace ultrasim::render
