#pragma once

#include <memory>

#include "ultrasim/render/display.hpp"
#include "ultrasim/render/settings.hpp"

namespace ultrasim::render {

// Options of the offscreen back end that the shared DisplaySettings do not carry.
struct OffscreenOptions {
  // Multisample anti-aliasing: 0 (off) or a sample count (2 or 4 on llvmpipe; clamped to the
  // implementation's GL_MAX_SAMPLES). 4 smooths the mesh lines at roughly 1.5x the fill cost.
  int msaa_samples = 0;
};

// A headless Display: Mesa's surfaceless EGL platform (no window system, no /dev/dri needed; on
// this kind of machine the llvmpipe software rasteriser), a GLES 3 context current with
// EGL_NO_SURFACE, and a framebuffer object with colour (RGBA8) and depth (24-bit) renderbuffers of
// width_px × height_px. Used by tests, headless runs and screenshots; the kiosk's DRM/KMS back end
// implements the same Display interface.
//
// Several OffscreenDisplays may exist one after another or side by side in one process; each makes
// its own context current when constructed. Not thread-safe: see Display.
class OffscreenDisplay final : public Display {
 public:
  // Brings up EGL and GLES 3 and makes the context current on the calling thread. Allocates.
  // Throws DisplayError (one line: EGL/GL call, error code, hint) when no EGL display, GLES 3
  // context or complete framebuffer can be had, and std::invalid_argument for a size outside
  // 1..16384 pixels.
  explicit OffscreenDisplay(const DisplaySettings& settings, const OffscreenOptions& options = {});
  ~OffscreenDisplay() override;

  int width_px() const override;
  int height_px() const override;
  void begin_frame() override;
  void end_frame() override;
  void read_pixels_into(RgbaImage& out) override;

  // Sample count actually in use (0 when multisampling is off).
  int msaa_samples() const;

  // The GL_RENDERER string of the context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
  const char* renderer_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ultrasim::render
