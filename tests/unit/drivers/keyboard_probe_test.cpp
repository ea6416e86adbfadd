#include "ultrasim/drivers/keyboard/keyboard_probe.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/input.h>
#include <unistd.h>

#include <cmath>
#include <cstring>

#include "evdev_records.hpp"

namespace ultrasim::drivers::keyboard {
namespace {

InputEvent key(std::uint16_t code, int value) {
  return {InputEvent::Kind::kKey, code, value};
}
InputEvent rel(std::uint16_t code, int value) {
  return {InputEvent::Kind::kRelative, code, value};
}

// Held keys move the probe at a steady rate whatever the repeat rate; R puts it back.
TEST(KeyboardProbeModel, HeldKeysMoveAtTheirRate) {
  KeyboardProbeSettings settings;
  settings.start_mm = {1.0, 2.0, -5.0};
  KeyboardProbeModel model(settings);
  model.advance(0);
  model.apply(key(KEY_RIGHT, 1));
  model.apply(key(KEY_PAGEDOWN, 1));
  model.apply(key(KEY_RIGHT, 2));  // auto-repeat: still held
  model.advance(500'000);
  EXPECT_NEAR(model.position_mm().x(), 1.0 + 20.0, 1e-9);
  EXPECT_NEAR(model.position_mm().z(), -5.0 + 20.0, 1e-9);
  model.apply(key(KEY_RIGHT, 0));
  model.apply(key(KEY_PAGEDOWN, 0));
  model.advance(1'000'000);
  EXPECT_NEAR(model.position_mm().x(), 21.0, 1e-9);
  model.apply(key(KEY_W, 1));
  model.advance(2'000'000);  // 1 s at 45°/s about the probe's x
  EXPECT_NEAR(model.orientation().angularDistance(Eigen::Quaterniond::Identity()), M_PI / 4, 1e-9);
  const Eigen::Vector3d beam = model.orientation() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(beam.x(), 0.0, 1e-9);  // rocked about x: the beam stays in the y–z plane
  model.apply(key(KEY_W, 0));
  model.apply(key(KEY_R, 1));
  EXPECT_EQ(model.position_mm(), settings.start_mm);
  EXPECT_TRUE(model.orientation().isApprox(Eigen::Quaterniond::Identity()));
}

TEST(KeyboardProbeModel, MouseMovesAndTheWheelPresses) {
  KeyboardProbeModel model({});
  model.apply(rel(REL_X, 50));
  model.apply(rel(REL_Y, -20));
  model.apply(rel(REL_WHEEL, -2));  // towards the user: press
  EXPECT_NEAR(model.position_mm().x(), 5.0, 1e-9);
  EXPECT_NEAR(model.position_mm().y(), -2.0, 1e-9);
  EXPECT_NEAR(model.position_mm().z(), -5.0 + 1.0, 1e-9);
}

TEST(TerminalKeyDecoder, ArrowsPagesAndLettersEvenWhenSplit) {
  TerminalKeyDecoder decoder;
  std::vector<InputEvent> out;
  const std::string first = "\x1b[C\x1b";
  const std::string second = "[6~wX\x1bOPd";
  decoder.feed(reinterpret_cast<const std::uint8_t*>(first.data()), first.size(), out);
  ASSERT_EQ(out.size(), 1u);
  decoder.feed(reinterpret_cast<const std::uint8_t*>(second.data()), second.size(), out);
  std::vector<std::uint16_t> codes;
  for (const auto& e : out) codes.push_back(e.code);
  // ESC O P (F1) is not ours and is dropped.
  EXPECT_EQ(codes, (std::vector<std::uint16_t>{KEY_RIGHT, KEY_PAGEDOWN, KEY_W, KEY_D}));
}

// Over an evdev stream (here a pipe): events move the probe; the device going away is a fault
// with the last pose kept and the device named.
TEST(KeyboardProbe, ReadsEvdevRecordsAndReportsTheDeviceGone) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  KeyboardProbe probe(fds[0], KeyboardProbe::Transport::kEvdev, "keyboard test", {});
  EXPECT_EQ(probe.latest(0)->position_mm, Eigen::Vector3d(0, 0, -5));
  ASSERT_TRUE(testing::write_input_event(fds[1], EV_KEY, KEY_LEFT, 1));
  ASSERT_TRUE(testing::write_input_event(fds[1], EV_SYN, SYN_REPORT, 0));
  EXPECT_EQ(probe.latest(10'000)->position_mm.x(), 0.0);  // pressed just now
  const auto moved = probe.latest(260'000);
  EXPECT_NEAR(moved->position_mm.x(), -10.0, 1e-9);
  EXPECT_EQ(moved->health, hal::PoseHealth::kOk);
  EXPECT_TRUE(probe.status_text().empty());
  ::close(fds[1]);
  const auto gone = probe.latest(300'000);
  EXPECT_EQ(gone->health, hal::PoseHealth::kFault);
  EXPECT_NEAR(gone->position_mm.x(), -11.6, 1e-9);
  EXPECT_EQ(probe.status_text(), "keyboard test: closed");
}

// A terminal sends a key again and again while it is held: it counts as held until the repeats
// stop for 150 ms.
TEST(KeyboardProbe, TerminalKeysHoldWhileTheyRepeat) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  KeyboardProbe probe(fds[0], KeyboardProbe::Transport::kTerminal, "terminal", {});
  probe.latest(0);
  ASSERT_EQ(::write(fds[1], "\x1b[B", 3), 3);
  probe.latest(0);
  EXPECT_NEAR(probe.latest(100'000)->position_mm.y(), 4.0, 1e-9);
  EXPECT_NEAR(probe.latest(400'000)->position_mm.y(), 4.0, 1e-9);  // released at 150 ms
  ::close(fds[1]);
}

TEST(KeyboardProbe, AMissingDeviceIsAClearError) {
  try {
    open_keyboard_probe("/dev/input/ultrasim-missing", {});
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/input/ultrasim-missing"), std::string::npos);
  }
}

}  // namespace
}  // namespace ultrasim::drivers::keyboard
