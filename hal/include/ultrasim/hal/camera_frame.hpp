#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::hal {

// One grey (8-bit luminance) camera image, row-major, `width` pixels a row with no padding.
// Pixel (u, v) has its centre at (u, v): the convention of OpenCV's camera model.
struct CameraFrame {
  TimestampUs timestamp_us = 0;  // when the exposure was taken (source clock, monotonic)
  std::uint32_t sequence = 0;    // increments per frame the source delivered; gaps mean drops
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> grey;  // width * height
};

// A pinhole camera with OpenCV's distortion model (k1, k2, p1, p2, k3). Pixels as in
// CameraFrame; focal lengths and principal point in pixels.
struct CameraIntrinsics {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  std::array<double, 5> distortion{};  // k1, k2, p1, p2, k3; zeros: an ideal lens
};

enum class FrameSourceHealth : std::uint8_t {
  kOk,     // delivering frames
  kEnded,  // a finite source (an image sequence) has delivered its last frame
  kFault,  // the device failed or went away (unplugged, read error); frames have stopped
};

// A camera, or anything that delivers camera frames in time order (an image sequence, a
// rendered view). Called from one tracking thread; it may block, the frame thread never calls it.
class FrameSource {
 public:
  virtual ~FrameSource() = default;

  // Waits up to timeout_us for the next frame and moves it into `frame` (reusing its buffer).
  // False when none came (timeout, end of a sequence or a fault: health() says which).
  virtual bool next_frame(CameraFrame& frame, TimestampUs timeout_us) = 0;

  virtual FrameSourceHealth health() const = 0;

  // Why the source is at fault or ended, or the last problem it got past (a file it skipped),
  // for the log and the status line; empty when there is nothing to say.
  virtual std::string_view status() const = 0;

  // Short human-readable name ("/dev/video0", "images:/path", ...).
  virtual std::string_view name() const = 0;
};

}  // namespace ultrasim::hal
