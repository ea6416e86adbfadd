// Choosing the dedicated display's output and mode, and the page-flip bookkeeping, on made-up
// connector lists (no display needed; the real page flips are tests/vm's).

#include "ultrasim/render/kms_selection.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace ultrasim::render {
namespace {

std::vector<KmsConnector> outputs() {
  return {
      {31, "DP-1", false, {}},
      {32,
       "HDMI-A-1",
       true,
       {{1920, 1080, 60, true, 0},
        {1920, 1080, 50, false, 1},
        {3840, 2160, 30, false, 2},
        {1280, 720, 60, false, 3},
        {1280, 720, 75, false, 4}}},
      {33, "HDMI-A-2", true, {{1024, 768, 60, false, 0}, {800, 600, 60, false, 1}}},
  };
}

TEST(KmsSelection, TheFirstConnectedOutputInItsPreferredMode) {
  const KmsChoice c = choose_kms_output(outputs(), {});
  EXPECT_EQ(c.connector, 1u);
  EXPECT_EQ(c.mode.width_px, 1920);
  EXPECT_EQ(c.mode.refresh_hz, 60);
  EXPECT_EQ(c.mode.index, 0);
}

TEST(KmsSelection, WithoutAPreferredModeTheLargestThenTheFastest) {
  const KmsChoice c = choose_kms_output(outputs(), {"HDMI-A-2", 0, 0, 0});
  EXPECT_EQ(c.connector, 2u);
  EXPECT_EQ(c.mode.width_px, 1024);
}

TEST(KmsSelection, AModeAskedForByItsSizeTakesTheFastestRefresh) {
  const KmsChoice c = choose_kms_output(outputs(), {"", 1280, 720, 0});
  EXPECT_EQ(c.mode.refresh_hz, 75);
  EXPECT_EQ(c.mode.index, 4);
  EXPECT_EQ(choose_kms_output(outputs(), {"", 1920, 1080, 50}).mode.index, 1);
}

void expect_error(const KmsRequest& request, const std::vector<KmsConnector>& list,
                  const std::string& message) {
  try {
    choose_kms_output(list, request);
    FAIL() << "expected: " << message;
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), message);
  }
}

TEST(KmsSelection, ErrorsSayWhatWasAskedAndWhatThereIs) {
  expect_error({"VGA-1", 0, 0, 0}, outputs(),
               "connector VGA-1 not found; outputs: DP-1, HDMI-A-1 (connected), HDMI-A-2 "
               "(connected)");
  expect_error({"DP-1", 0, 0, 0}, outputs(), "connector DP-1 has no display connected");
  expect_error({"HDMI-A-2", 1920, 1080, 0}, outputs(),
               "mode 1920x1080 not offered by HDMI-A-2; offered: 1024x768@60, 800x600@60");
  expect_error({}, {{31, "DP-1", false, {}}}, "no connected display; outputs: DP-1");
  expect_error({}, {}, "no connected display; outputs: none");
}

// The kernel holds the buffer on screen and at most one flip: a second flip before the first
// completes is refused, and a completed flip frees the buffer it replaced.
TEST(FlipQueue, OneFlipAtATimeAndTheReplacedBufferComesBack) {
  FlipQueue q;
  EXPECT_TRUE(q.queue(0xA));
  EXPECT_EQ(q.complete(), 0u);  // the first flip (the modeset) replaced nothing
  EXPECT_EQ(q.on_screen(), 0xAu);
  EXPECT_TRUE(q.queue(0xB));
  EXPECT_TRUE(q.pending());
  EXPECT_FALSE(q.queue(0xC));
  EXPECT_EQ(q.complete(), 0xAu);
  EXPECT_EQ(q.on_screen(), 0xBu);
  EXPECT_FALSE(q.pending());
  EXPECT_EQ(q.complete(), 0u);  // nothing pending
  EXPECT_EQ(q.flips(), 2);
}

}  // namespace
}  // namespace ultrasim::render
