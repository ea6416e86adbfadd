#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/input.h>
#include <unistd.h>

#include <vector>

#include "evdev_records.hpp"
#include "ultrasim/drivers/touch/evdev_pointer.hpp"
#include "ultrasim/drivers/touch/pointer_decoder.hpp"

namespace ultrasim::drivers::touch {
namespace {

using Kind = hal::PointerEvent::Kind;

std::vector<hal::PointerEvent> decode(PointerDecoder& d, std::vector<RawInputEvent> records) {
  std::vector<hal::PointerEvent> out;
  for (const auto& r : records) d.feed(r, out);
  return out;
}

constexpr RawInputEvent kReport{EV_SYN, SYN_REPORT, 0};

// A single-touch screen, 0..4095 on both axes, on a 1280×720 display: a tap where it lands.
TEST(PointerDecoder, ATouchIsAMoveAndPressThenARelease) {
  PointerDecoder d(1280, 720, {0, 4095}, {0, 4095});
  const auto down =
      decode(d, {{EV_ABS, ABS_X, 4095}, {EV_ABS, ABS_Y, 2048}, {EV_KEY, BTN_TOUCH, 1}, kReport});
  ASSERT_EQ(down.size(), 2u);
  EXPECT_EQ(down[0].kind, Kind::kMove);
  EXPECT_FLOAT_EQ(down[0].x_px, 1279.0f);
  EXPECT_NEAR(down[0].y_px, 359.6f, 0.1f);
  EXPECT_EQ(down[1].kind, Kind::kPress);
  const auto up = decode(d, {{EV_KEY, BTN_TOUCH, 0}, kReport});
  ASSERT_EQ(up.size(), 1u);
  EXPECT_EQ(up[0].kind, Kind::kRelease);
  EXPECT_FLOAT_EQ(up[0].x_px, 1279.0f) << "released where it was";
}

TEST(PointerDecoder, OnlyTheFirstMultiTouchSlotCounts) {
  PointerDecoder d(100, 100, {0, 99}, {0, 99});
  const auto first = decode(d, {{EV_ABS, ABS_MT_SLOT, 0},
                                {EV_ABS, ABS_MT_TRACKING_ID, 7},
                                {EV_ABS, ABS_MT_POSITION_X, 10},
                                {EV_ABS, ABS_MT_POSITION_Y, 20},
                                {EV_ABS, ABS_MT_SLOT, 1},
                                {EV_ABS, ABS_MT_TRACKING_ID, 8},
                                {EV_ABS, ABS_MT_POSITION_X, 90},
                                kReport});
  ASSERT_EQ(first.size(), 2u);
  EXPECT_FLOAT_EQ(first[0].x_px, 10.0f);
  EXPECT_EQ(first[1].kind, Kind::kPress);
  const auto second_lifts = decode(d, {{EV_ABS, ABS_MT_TRACKING_ID, -1}, kReport});
  EXPECT_TRUE(second_lifts.empty()) << "slot 1 is still addressed: its lift is not ours";
  const auto first_lifts =
      decode(d, {{EV_ABS, ABS_MT_SLOT, 0}, {EV_ABS, ABS_MT_TRACKING_ID, -1}, kReport});
  ASSERT_EQ(first_lifts.size(), 1u);
  EXPECT_EQ(first_lifts[0].kind, Kind::kRelease);
}

TEST(PointerDecoder, AMouseMovesACursorKeptOnTheScreenAndClicksAndScrolls) {
  PointerDecoder d(200, 100);
  auto out = decode(d, {{EV_REL, REL_X, 30}, {EV_REL, REL_Y, -500}, kReport});
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FLOAT_EQ(out[0].x_px, 130.0f);
  EXPECT_FLOAT_EQ(out[0].y_px, 0.0f);
  out = decode(d, {{EV_KEY, BTN_LEFT, 1},
                   kReport,
                   {EV_KEY, BTN_LEFT, 0},
                   kReport,
                   {EV_REL, REL_WHEEL, -2},
                   kReport});
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].kind, Kind::kPress);
  EXPECT_EQ(out[1].kind, Kind::kRelease);
  EXPECT_EQ(out[2].kind, Kind::kWheel);
  EXPECT_FLOAT_EQ(out[2].wheel_notches, -2.0f);
}

TEST(PointerDecoder, RecordsBeforeADropAreDiscarded) {
  PointerDecoder d(100, 100, {0, 99}, {0, 99});
  const auto out = decode(d, {{EV_ABS, ABS_X, 50},
                              {EV_KEY, BTN_TOUCH, 1},
                              {EV_SYN, SYN_DROPPED, 0},
                              {EV_ABS, ABS_Y, 5},
                              kReport,
                              {EV_ABS, ABS_Y, 60},
                              kReport});
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].kind, Kind::kMove);
  EXPECT_FLOAT_EQ(out[0].y_px, 60.0f);
}

// Over an evdev stream (here a pipe): records become events; the device going away is said.
TEST(EvdevPointer, ReadsWithoutBlockingAndSaysWhenTheDeviceIsGone) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  ASSERT_EQ(::fcntl(fds[0], F_SETFL, O_NONBLOCK), 0);
  EvdevPointer pointer(fds[0], "/dev/input/event9", PointerDecoder(1280, 720));
  EXPECT_TRUE(pointer.poll().empty());
  ASSERT_TRUE(testing::write_input_event(fds[1], EV_REL, REL_X, 10));
  ASSERT_TRUE(testing::write_input_event(fds[1], EV_KEY, BTN_LEFT, 1));
  ASSERT_TRUE(testing::write_input_event(fds[1], EV_SYN, SYN_REPORT, 0));
  const auto events = pointer.poll();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_FLOAT_EQ(events[0].x_px, 650.0f);
  EXPECT_EQ(events[1].kind, Kind::kPress);
  EXPECT_TRUE(pointer.status_text().empty());
  ::close(fds[1]);
  EXPECT_TRUE(pointer.poll().empty());
  EXPECT_EQ(pointer.status_text(), "/dev/input/event9: closed");
}

TEST(EvdevPointer, AMissingDeviceIsNamed) {
  try {
    open_evdev_pointer("/dev/input/no-such-event", 1280, 720);
    FAIL() << "opened a missing device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/input/no-such-event"), std::string::npos);
  }
}

}  // namespace
}  // namespace ultrasim::drivers::touch
