#pragma once

#include "ultrasim/render/rgba_image.hpp"

namespace ultrasim::render {

// Where frames go: an offscreen framebuffer today, a DRM/KMS scan-out later. A Display owns the
// EGL display and the GLES 3 context; the context is current on the thread that constructed the
// Display, and every member (and every GL call, SceneRenderer included) must come from that
// thread, the render thread.
//
// One frame: begin_frame(), draw with GLES into the bound framebuffer, end_frame().
class Display {
 public:
  Display() = default;
  Display(const Display&) = delete;
  Display& operator=(const Display&) = delete;
  virtual ~Display() = default;

  // Size of the drawable in pixels; constant for the Display's lifetime.
  virtual int width_px() const = 0;
  virtual int height_px() const = 0;

  // Binds the frame's framebuffer and sets the viewport to the whole drawable. No allocation.
  virtual void begin_frame() = 0;

  // Finishes the frame (resolves multisampling, later: queues the page flip). When it returns
  // the frame counts as presented (the probe-to-photon measure ends here). No allocation.
  virtual void end_frame() = 0;

  // Copies the last finished frame into out, rows top first. Waits for the GPU (a pipeline
  // stall: for tests, screenshots and soak checks, not for every kiosk frame). Allocates only
  // when out is smaller than the drawable.
  virtual void read_pixels_into(RgbaImage& out) = 0;

  // Same as read_pixels_into, into a fresh image. Allocates.
  RgbaImage read_pixels() {
    RgbaImage image;
    read_pixels_into(image);
    return image;
  }
};

}  // namespace ultrasim::render
