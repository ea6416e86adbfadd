#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "ultrasim/render/display.hpp"
#include "ultrasim/render/kms_selection.hpp"

namespace ultrasim::render {

struct KmsOptions {
  std::string device = "/dev/dri/card0";
  KmsRequest output;          // which connector and mode
  bool force_legacy = false;  // legacy modeset and page flip even where atomic commits work
};

// The dedicated display, in kmscube's manner: a DRM/KMS output driven directly (no window
// system), GLES 3 rendering into GBM buffers through EGL, each frame shown by a page flip that
// the kernel performs at vblank. Atomic commits where the driver has them, legacy modeset and
// page flip otherwise. The output's previous mode is restored on destruction.
//
// end_frame() swaps, queues the flip and waits for it to complete: frames are paced by the
// display's refresh, and a frame counts as presented at the flip's vblank time
// (last_flip_us()). Not thread-safe: see Display.
class KmsDisplay final : public Display {
 public:
  // Opens the device, chooses the output (choose_kms_output), sets the mode on the first frame.
  // Throws DisplayError naming the device or call and the cause (no such device, no connected
  // display, no GBM/EGL, mode not offered).
  explicit KmsDisplay(const KmsOptions& options);
  ~KmsDisplay() override;

  int width_px() const override;
  int height_px() const override;
  void begin_frame() override;
  void end_frame() override;
  // Reads the buffer on screen (mapped through GBM). Allocates when `out` is smaller.
  void read_pixels_into(RgbaImage& out) override;

  bool atomic() const;
  const std::string& connector_name() const;
  const KmsMode& mode() const;
  std::int64_t flips() const;
  // When the last flip completed: the kernel's vblank time on CLOCK_MONOTONIC, µs.
  std::int64_t last_flip_us() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ultrasim::render
