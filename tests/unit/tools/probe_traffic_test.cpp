// The bring-up tool's traffic statistics: rates, interval quantiles, missed frames and refusals.

#include "ultrasim/tools/probe_traffic.hpp"

#include <gtest/gtest.h>

namespace ultrasim::tools {
namespace {

namespace pc = drivers::probe_can;

TEST(ProbeTraffic, CountsRatesIntervalsMissedFramesAndRefusals) {
  const pc::ProbeCodec codec;
  ProbeTraffic traffic;
  hal::TimestampUs t = 0;
  for (int i = 0; i < 100; ++i) {
    if (i == 40 || i == 41 || i == 42) continue;          // three dropped
    const hal::TimestampUs jitter = i == 70 ? 3'000 : 0;  // one late frame
    pc::ProbeOrientation o;
    o.sequence = static_cast<std::uint8_t>(i);
    const hal::ReceivedCanFrame r{codec.encode(o), t + i * 5'000 + jitter};
    ASSERT_TRUE(traffic.add(r).has_value());
  }
  hal::ReceivedCanFrame bad{codec.encode(pc::ProbeStatus{}), 1'000};
  bad.frame.data[0] ^= 0xFF;
  EXPECT_FALSE(traffic.add(bad).has_value());

  EXPECT_EQ(traffic.frames(), 98);
  const auto& o = traffic.by_id().at(pc::ProbeCodec::kOrientationId);
  EXPECT_EQ(o.frames, 97);
  EXPECT_EQ(o.missed, 3);
  EXPECT_EQ(o.duplicates, 0);
  EXPECT_NEAR(o.rate_hz(), 96.0 / 0.495, 1e-9);
  EXPECT_EQ(o.interval_quantile_us(0.5), 5'000);
  EXPECT_EQ(o.interval_quantile_us(1.0), 20'000);  // the gap of three dropped frames
  EXPECT_EQ(o.interval_quantile_us(0.0), 2'000);   // the frame after the late one
  EXPECT_EQ(traffic.errors()[static_cast<int>(pc::DecodeError::kBadChecksum)], 1);
  EXPECT_EQ(traffic.by_id().count(pc::ProbeCodec::kStatusId), 0u);
  EXPECT_NE(traffic.json().find("\"ProbeOrientation\": {\"frames\": 97, \"rate_hz\": 193.94"),
            std::string::npos)
      << traffic.json();
}

}  // namespace
}  // namespace ultrasim::tools

namespace ultrasim::tools {
namespace {

class QueueBus final : public hal::CanBus {
 public:
  bool send(const hal::CanFrame& frame, hal::TimestampUs) override {
    sent.push_back(frame);
    return true;
  }
  bool receive(hal::ReceivedCanFrame& out) override {
    if (next == queue.size()) return false;
    out = queue[next++];
    return true;
  }
  hal::CanBusStats stats() const override { return {}; }
  std::vector<hal::ReceivedCanFrame> queue;
  std::size_t next = 0;
  std::vector<hal::CanFrame> sent;
};

TEST(TrafficTap, AccountsWhatTheDriverReadsAndReportsTheDriver) {
  const drivers::probe_can::ProbeCodec codec;
  QueueBus bus;
  drivers::probe_can::ProbeStatus status;
  status.orientation_rate_hz = 200;
  bus.queue.push_back({codec.encode(status), 0});
  for (int i = 0; i < 5; ++i) {
    drivers::probe_can::ProbeOrientation o;
    o.sequence = static_cast<std::uint8_t>(i);
    bus.queue.push_back({codec.encode(o), 1'000 + i * 5'000});
  }
  ProbeTraffic traffic;
  TrafficTap tap(bus, traffic);
  int seen = 0;
  tap.on_frame(
      [](void* context, const hal::ReceivedCanFrame&,
         const std::expected<drivers::probe_can::ProbeMessage, drivers::probe_can::DecodeError>&) {
        ++*static_cast<int*>(context);
      },
      &seen);
  drivers::probe_can::CanProbe probe(tap, {});
  probe.latest(30'000);
  probe.latest(31'000);
  EXPECT_EQ(seen, 6);
  EXPECT_EQ(traffic.frames(), 6);
  EXPECT_TRUE(bus.sent.empty()) << "the status already said 200 Hz: nothing to ask for";
  EXPECT_TRUE(probe.send_zero(40'000));
  EXPECT_EQ(bus.sent.size(), 1u) << "commands go through the tap";
  const std::string json = driver_json(probe, tap.stats());
  EXPECT_NE(json.find("\"state\": \"streaming\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"orientation_interval_us\": {\"count\": 4, \"min\": 5000, \"p50\": 5100"),
            std::string::npos)
      << json;
  EXPECT_NE(json.find("\"histogram_100us\": {\"5000\": 4}"), std::string::npos) << json;
}

}  // namespace
}  // namespace ultrasim::tools
