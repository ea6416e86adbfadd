// The simulated probe firmware against our own host driver over a loopback bus: the driver
// configures it, streams from it, re-rates it and zeroes it, as it would a real probe; and the
// round-trip meter that times the bring-up tool's end-to-end check.

#include "ultrasim/tools/simulated_probe_firmware.hpp"

#include <gtest/gtest.h>

#include <deque>

#include "ultrasim/drivers/probe_can/can_probe.hpp"
#include "ultrasim/tools/round_trip_meter.hpp"

namespace ultrasim::tools {
namespace {

// The host's end of a bus whose other end is the firmware; frames take no time.
class Loopback final : public hal::CanBus {
 public:
  explicit Loopback(SimulatedProbeFirmware& firmware) : firmware_(firmware) {}
  bool send(const hal::CanFrame& frame, hal::TimestampUs) override {
    firmware_.receive(frame);
    return true;
  }
  bool receive(hal::ReceivedCanFrame& out) override {
    if (queue_.empty()) return false;
    out = queue_.front();
    queue_.pop_front();
    return true;
  }
  hal::CanBusStats stats() const override { return {}; }
  void run_firmware(hal::TimestampUs now_us) {
    std::vector<hal::CanFrame> out;
    firmware_.step(now_us, out);
    for (const auto& f : out) queue_.push_back({f, now_us});
  }

 private:
  SimulatedProbeFirmware& firmware_;
  std::deque<hal::ReceivedCanFrame> queue_;
};

TEST(SimulatedProbeFirmware, TheHostDriverConfiguresStreamsAndZeroesIt) {
  SimulatedProbeFirmware firmware;
  Loopback bus(firmware);
  drivers::probe_can::CanProbeSettings settings;
  settings.expected_rate_hz = 100.0;  // asks the firmware (at 200 Hz) for 100
  drivers::probe_can::CanProbe probe(bus, settings);
  for (hal::TimestampUs t = 0; t <= 1'000'000; t += 1'000) {
    bus.run_firmware(t);
    probe.latest(t);
  }
  EXPECT_EQ(probe.state(), drivers::probe_can::CanProbe::State::kStreaming);
  EXPECT_EQ(firmware.orientation_rate_hz(), 100);
  EXPECT_GE(firmware.commands_received(), 1);
  EXPECT_EQ(firmware.commands_refused(), 0);
  // About 100 orientations a second once re-rated, none missed.
  const auto before = probe.counters().orientations;
  for (hal::TimestampUs t = 1'001'000; t <= 2'000'000; t += 1'000) {
    bus.run_firmware(t);
    probe.latest(t);
  }
  EXPECT_NEAR(probe.counters().orientations - before, 100, 2);
  EXPECT_EQ(probe.counters().missed, 0);
  EXPECT_EQ(probe.counters().refused, 0);
  // The firmware turns; zeroed, it reports identity.
  EXPECT_GT(probe.latest(2'000'000)->orientation.angularDistance(Eigen::Quaterniond::Identity()),
            0.1);
  ASSERT_TRUE(probe.send_zero(2'000'000));
  bus.run_firmware(2'010'000);
  const auto zeroed = probe.latest(2'010'000);
  EXPECT_LT(zeroed->orientation.angularDistance(Eigen::Quaterniond::Identity()), 1e-3);
  EXPECT_EQ(zeroed->health, hal::PoseHealth::kOk);
  // Its compression input presses the host's probe in.
  ASSERT_TRUE(probe.last_input().has_value());
}

TEST(RoundTripMeter, TimesEachRequestToItsAnswer) {
  RoundTripMeter meter;
  meter.status_received(50);  // unsolicited: ignored
  meter.sent(100);
  meter.status_received(90);  // before the request: not its answer
  meter.status_received(350);
  meter.sent(1'000);
  meter.sent(2'000);  // the one before was never answered
  meter.status_received(2'100);
  meter.sent(3'000);
  meter.give_up();
  EXPECT_EQ(meter.round_trips_us(), (std::vector<std::int64_t>{250, 100}));
  EXPECT_EQ(meter.lost(), 2);
  EXPECT_EQ(meter.json(),
            "{\"count\": 2, \"lost\": 2, \"p50_us\": 100, \"p99_us\": 250, \"max_us\": 250}");
}

}  // namespace
}  // namespace ultrasim::tools
