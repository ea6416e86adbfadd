// The V4L2 camera driver in a real kernel: inside the test VM, the kernel's virtual video
// driver (vivid, loaded by run_in_vm.sh) is a camera at /dev/video0 drawing test patterns.

#include <gtest/gtest.h>

#include <algorithm>

#include "ultrasim/drivers/camera/v4l2_camera.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"

namespace ultrasim::drivers::camera {
namespace {

TEST(V4l2CameraVm, ReadsFramesFromAVirtualCamera) {
  posix::MonotonicClock clock;
  V4l2CameraSettings settings;
  settings.device = "/dev/video0";
  settings.frames_per_second = 30.0;
  V4l2CameraSource camera(settings, clock);
  ASSERT_EQ(camera.health(), hal::FrameSourceHealth::kOk) << camera.status();
  hal::CameraFrame frame;
  hal::TimestampUs last_us = -1;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(camera.next_frame(frame, 2'000'000)) << camera.status();
    EXPECT_GT(frame.width, 0);
    EXPECT_GT(frame.height, 0);
    EXPECT_EQ(frame.grey.size(), static_cast<std::size_t>(frame.width) * frame.height);
    EXPECT_EQ(frame.sequence, static_cast<std::uint32_t>(i));
    EXPECT_GT(frame.timestamp_us, last_us);
    last_us = frame.timestamp_us;
  }
  // vivid draws colour bars: many grey levels, not a blank or garbage buffer.
  const auto [lo, hi] = std::minmax_element(frame.grey.begin(), frame.grey.end());
  EXPECT_GT(*hi - *lo, 100);
  std::printf("vivid camera: %d x %d, grey %d..%d\n", frame.width, frame.height, *lo, *hi);
}

}  // namespace
}  // namespace ultrasim::drivers::camera
