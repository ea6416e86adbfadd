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
