#pragma once

#include <memory>
#include <string>

#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::camera {

struct V4l2CameraSettings {
  std::string device = "/dev/video0";
  // Asked of the driver; the camera may give another size or rate (frames come as they are).
  int width_px = 640;
  int height_px = 480;
  double frames_per_second = 60.0;
  // While the device is missing or failing, how often to try to open it again (hot-plug).
  hal::TimestampUs reopen_interval_us = 1'000'000;
};

// A USB/CSI camera through OpenCV's V4L2 capture. A camera that is missing, or that stops
// delivering (unplugged), puts the source at fault with the device and the cause in status();
// it is opened again, every reopen_interval_us, until it comes back.
class V4l2CameraSource final : public hal::FrameSource {
 public:
  // Does not throw for a missing device (the kiosk may start before the camera is plugged in):
  // the source starts at fault instead. `clock` timestamps the frames (when each was read).
  V4l2CameraSource(const V4l2CameraSettings& settings, const hal::Clock& clock);
  ~V4l2CameraSource() override;

  // Blocks in the driver until a frame comes (V4L2 delivers at the camera's rate). Allocates.
  bool next_frame(hal::CameraFrame& frame, hal::TimestampUs timeout_us) override;
  hal::FrameSourceHealth health() const override { return health_; }
  std::string_view status() const override { return status_; }
  std::string_view name() const override { return settings_.device; }

 private:
  bool open();

  struct Impl;
  std::unique_ptr<Impl> impl_;
  V4l2CameraSettings settings_;
  const hal::Clock& clock_;
  hal::FrameSourceHealth health_ = hal::FrameSourceHealth::kFault;
  std::string status_;
  hal::TimestampUs last_open_attempt_us_ = 0;
  bool tried_ = false;
  std::uint32_t sequence_ = 0;
};

}  // namespace ultrasim::drivers::camera
