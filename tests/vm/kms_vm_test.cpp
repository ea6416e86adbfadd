// The DRM/KMS display in a real kernel: inside the test VM, QEMU's virtio-gpu is a KMS device
// with one virtual output. Frames are drawn with GLES through GBM and EGL, shown by page flips,
// and read back from the buffer on screen; atomic commits and the legacy path both.

#include <GLES3/gl3.h>
#include <gtest/gtest.h>

#include "ultrasim/render/display_error.hpp"
#include "ultrasim/render/kms_display.hpp"

namespace ultrasim::render {
namespace {

void run_frames(bool force_legacy) {
  KmsOptions options;
  options.force_legacy = force_legacy;
  KmsDisplay display(options);
  std::printf("KMS: %s %dx%d@%d, %s\n", display.connector_name().c_str(), display.width_px(),
              display.height_px(), display.mode().refresh_hz,
              display.atomic() ? "atomic" : "legacy");
  EXPECT_EQ(display.atomic(), !force_legacy);
  std::int64_t last_flip = 0;
  for (int i = 0; i < 6; ++i) {
    display.begin_frame();
    glClearColor(i % 2 ? 1.0f : 0.0f, 0.5f, i % 2 ? 0.0f : 1.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    display.end_frame();
    if (i > 0) {
      EXPECT_GT(display.last_flip_us(), last_flip) << "frame " << i;
      last_flip = display.last_flip_us();
    }
  }
  EXPECT_EQ(display.flips(), 6);  // the modeset and five flips
  // The last frame (i = 5: red 255, green 128, blue 0) is what the output shows.
  const RgbaImage shown = display.read_pixels();
  ASSERT_EQ(shown.width, display.width_px());
  const std::uint8_t* p = shown.at(shown.width / 2, shown.height / 2);
  EXPECT_EQ(p[0], 255);
  EXPECT_NEAR(p[1], 128, 1);
  EXPECT_EQ(p[2], 0);
}

TEST(KmsDisplayVm, AtomicCommitsShowFramesAtVblank) {
  run_frames(false);
}
TEST(KmsDisplayVm, TheLegacyPathShowsThemToo) {
  run_frames(true);
}

TEST(KmsDisplayVm, AMissingConnectorIsNamedWithTheOutputsThereAre) {
  KmsOptions options;
  options.output.connector = "HDMI-A-9";
  try {
    KmsDisplay display(options);
    FAIL() << "expected an error";
  } catch (const DisplayError& e) {
    EXPECT_NE(std::string(e.what()).find("connector HDMI-A-9 not found; outputs: Virtual-1"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ultrasim::render
