#include "ultrasim/render/offscreen_display.hpp"

#include <GLES3/gl3.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>
#include <string>

#include "ultrasim/render/display_error.hpp"

namespace ultrasim::render {
namespace {

DisplaySettings small_settings() {
  DisplaySettings settings;
  settings.width_px = 320;
  settings.height_px = 200;
  return settings;
}

void expect_pixel(const RgbaImage& image, int x, int y, int r, int g, int b) {
  const std::uint8_t* p = image.at(x, y);
  EXPECT_NEAR(p[0], r, 1) << "at " << x << "," << y;
  EXPECT_NEAR(p[1], g, 1) << "at " << x << "," << y;
  EXPECT_NEAR(p[2], b, 1) << "at " << x << "," << y;
  EXPECT_EQ(p[3], 255) << "at " << x << "," << y;
}

// Clears the frame to one colour and the top 10 rows to another, so a read-back also shows
// whether rows come back top first.
RgbaImage clear_and_read(OffscreenDisplay& display) {
  display.begin_frame();
  glClearColor(0.2f, 0.4f, 0.6f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_SCISSOR_TEST);
  // GL's y runs up: the top 10 rows are the last 10.
  glScissor(0, display.height_px() - 10, display.width_px(), 10);
  glClearColor(1.0f, 0.0f, 0.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  glDisable(GL_SCISSOR_TEST);
  display.end_frame();
  return display.read_pixels();
}

TEST(OffscreenDisplay, ClearsAndReadsBackTopRowFirst) {
  OffscreenDisplay display(small_settings());
  EXPECT_EQ(display.width_px(), 320);
  EXPECT_EQ(display.height_px(), 200);
  EXPECT_EQ(display.msaa_samples(), 0);
  const RgbaImage image = clear_and_read(display);
  ASSERT_EQ(image.width, 320);
  ASSERT_EQ(image.height, 200);
  ASSERT_EQ(image.rgba.size(), 320u * 200u * 4u);
  expect_pixel(image, 0, 0, 255, 0, 0);
  expect_pixel(image, 319, 9, 255, 0, 0);
  expect_pixel(image, 0, 10, 51, 102, 153);
  expect_pixel(image, 160, 100, 51, 102, 153);
  expect_pixel(image, 319, 199, 51, 102, 153);
}

TEST(OffscreenDisplay, ReadPixelsIntoReusesTheImage) {
  OffscreenDisplay display(small_settings());
  RgbaImage image;
  display.begin_frame();
  display.end_frame();
  display.read_pixels_into(image);
  const std::uint8_t* storage = image.rgba.data();
  display.read_pixels_into(image);
  EXPECT_EQ(image.rgba.data(), storage);
}

TEST(OffscreenDisplay, MultisampledFrameResolvesForReadBack) {
  OffscreenOptions options;
  options.msaa_samples = 4;
  OffscreenDisplay display(small_settings(), options);
  EXPECT_GT(display.msaa_samples(), 1);
  const RgbaImage image = clear_and_read(display);
  expect_pixel(image, 5, 5, 255, 0, 0);
  expect_pixel(image, 160, 100, 51, 102, 153);
}

TEST(OffscreenDisplay, CreatesAndDestroysThreeTimesInOneProcess) {
  for (int i = 0; i < 3; ++i) {
    OffscreenDisplay display(small_settings());
    const RgbaImage image = clear_and_read(display);
    expect_pixel(image, 100, 100, 51, 102, 153);
  }
}

TEST(OffscreenDisplay, TwoDisplaysSideBySideKeepTheirOwnContexts) {
  auto first = std::make_unique<OffscreenDisplay>(small_settings());
  DisplaySettings other = small_settings();
  other.width_px = 64;
  other.height_px = 48;
  OffscreenDisplay second(other);
  expect_pixel(clear_and_read(*first), 10, 100, 51, 102, 153);
  const RgbaImage image = clear_and_read(second);
  EXPECT_EQ(image.width, 64);
  expect_pixel(image, 10, 40, 51, 102, 153);
  // Destroying one must not terminate the EGL display under the other.
  first.reset();
  expect_pixel(clear_and_read(second), 10, 0, 255, 0, 0);
}

TEST(OffscreenDisplay, RejectsSizesOutsideRange) {
  DisplaySettings settings = small_settings();
  settings.width_px = 0;
  EXPECT_THROW(OffscreenDisplay{settings}, std::invalid_argument);
  settings.width_px = 20000;
  EXPECT_THROW(OffscreenDisplay{settings}, std::invalid_argument);
}

TEST(OffscreenDisplay, MissingDriverIsOneClearDisplayError) {
  // Point Mesa's loader at an empty folder: the same failure as libgl1-mesa-dri not installed.
  // Only meaningful when no display is alive (the driver is loaded at eglInitialize).
  ASSERT_EQ(setenv("LIBGL_DRIVERS_PATH", "/nonexistent-ultrasim-test", 1), 0);
  // Keep the expected loader complaint out of the test log.
  ASSERT_EQ(setenv("EGL_LOG_LEVEL", "fatal", 1), 0);
  std::string message;
  try {
    OffscreenDisplay display(small_settings());
  } catch (const DisplayError& error) {
    message = error.what();
  }
  unsetenv("LIBGL_DRIVERS_PATH");
  unsetenv("EGL_LOG_LEVEL");
  if (message.empty()) GTEST_SKIP() << "this EGL loaded a driver without LIBGL_DRIVERS_PATH";
  EXPECT_NE(message.find("eglInitialize failed: EGL_NOT_INITIALIZED"), std::string::npos)
      << message;
  EXPECT_NE(message.find("libgl1-mesa-dri"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  // And the process recovers once the driver is back.
  OffscreenDisplay display(small_settings());
  expect_pixel(clear_and_read(display), 1, 150, 51, 102, 153);
}

}  // namespace
}  // namespace ultrasim::render
