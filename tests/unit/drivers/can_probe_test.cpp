// The CAN probe as a pose source: fresh, stale and faulty poses, bad frames counted and never
// shown, dropped frames counted, host commands on the bus.

#include "ultrasim/drivers/probe_can/can_probe.hpp"

#include <gtest/gtest.h>

#include <deque>
#include <vector>

namespace ultrasim::drivers::probe_can {
namespace {

class FakeBus final : public hal::CanBus {
 public:
  bool send(const hal::CanFrame& frame, hal::TimestampUs) override {
    if (refuse_sends) return false;
    sent.push_back(frame);
    return true;
  }
  bool receive(hal::ReceivedCanFrame& out) override {
    if (queue.empty()) return false;
    out = queue.front();
    queue.pop_front();
    return true;
  }
  hal::CanBusStats stats() const override { return stats_; }

  std::deque<hal::ReceivedCanFrame> queue;
  std::vector<hal::CanFrame> sent;
  hal::CanBusStats stats_;
  bool refuse_sends = false;
};

class CanProbeTest : public ::testing::Test {
 protected:
  void orientation_at(hal::TimestampUs t_us, const Eigen::Quaterniond& q, std::uint8_t seq) {
    bus_.queue.push_back({codec_.encode(ProbeOrientation{q, seq}), t_us});
  }
  Eigen::Quaterniond about_z(double degrees) const {
    return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::UnitZ()));
  }
  FakeBus bus_;
  ProbeCodec codec_;
};

TEST_F(CanProbeTest, FreshOrientationsBecomePosesThroughTheMount) {
  CanProbeSettings settings;
  settings.position_mm = {1, 2, 3};
  settings.mount = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  CanProbe probe(bus_, settings);
  EXPECT_FALSE(probe.latest(0).has_value()) << "no pose before the first orientation";
  orientation_at(1'000, about_z(10), 0);
  orientation_at(6'000, about_z(20), 1);
  const auto pose = probe.latest(6'500);
  ASSERT_TRUE(pose.has_value());
  EXPECT_EQ(pose->health, hal::PoseHealth::kOk);
  EXPECT_EQ(pose->timestamp_us, 6'000);
  EXPECT_EQ(pose->position_mm, Eigen::Vector3d(1, 2, 3));
  EXPECT_LT(pose->orientation.angularDistance(about_z(20) * settings.mount), 1e-4);
  EXPECT_TRUE(hal::is_valid(*pose));
  EXPECT_EQ(probe.counters().orientations, 2);
  EXPECT_EQ(probe.name(), "can0");
}

// The compression input presses the face in along the probe's beam, scaled and limited.
TEST_F(CanProbeTest, CompressionPressesAlongTheBeam) {
  CanProbeSettings settings;
  settings.position_mm = {10, 0, 0};
  settings.compression_mm_per_n = 2.0;
  settings.max_compression_mm = 15.0;
  CanProbe probe(bus_, settings);
  // Tilted 90° about x: the beam (+z of the probe) points along patient −y.
  const Eigen::Quaterniond tilted(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  orientation_at(1'000, tilted, 0);
  EXPECT_LT((probe.latest(1'100)->position_mm - Eigen::Vector3d(10, 0, 0)).norm(), 1e-9);
  ProbeInput input;
  input.compression_force_n = 3.0;
  bus_.queue.push_back({codec_.encode(input), 1'200});
  EXPECT_LT((probe.latest(1'300)->position_mm - Eigen::Vector3d(10, -6, 0)).norm(), 1e-6);
  input.compression_force_n = 100.0;
  input.sequence = 1;
  bus_.queue.push_back({codec_.encode(input), 1'400});
  EXPECT_LT((probe.latest(1'500)->position_mm - Eigen::Vector3d(10, -15, 0)).norm(), 1e-6);
  EXPECT_TRUE(probe.status_text().empty());
  settings.compression_mm_per_n = -1.0;
  EXPECT_THROW(CanProbe(bus_, settings), std::invalid_argument);
}

TEST_F(CanProbeTest, NoOrientationForThreePeriodsIsStaleWithTheLastGoodPoseKept) {
  CanProbe probe(bus_, {});
  orientation_at(0, about_z(10), 0);
  EXPECT_EQ(probe.latest(15'000)->health, hal::PoseHealth::kOk);  // 3 periods at 200 Hz
  const auto stale = probe.latest(15'001);
  EXPECT_EQ(stale->health, hal::PoseHealth::kStale);
  EXPECT_EQ(probe.status_text(), "can0: no orientation for 15 ms");
  EXPECT_LT(stale->orientation.angularDistance(about_z(10)), 1e-4);
  probe.latest(20'000);
  EXPECT_EQ(probe.counters().stale_events, 1);
  orientation_at(20'000, about_z(30), 1);
  EXPECT_EQ(probe.latest(20'100)->health, hal::PoseHealth::kOk);

  // A status saying the rate is now 50 Hz: stale after 60 ms.
  ProbeStatus status;
  status.orientation_rate_hz = 52;  // multiples of 4: 52 Hz, stale after 57.7 ms
  bus_.queue.push_back({codec_.encode(status), 20'200});
  EXPECT_EQ(probe.latest(77'000)->health, hal::PoseHealth::kOk);
  EXPECT_EQ(probe.latest(78'000)->health, hal::PoseHealth::kStale);
  EXPECT_EQ(probe.counters().stale_events, 2);
}

TEST_F(CanProbeTest, BadFramesAreCountedAndNeverShown) {
  CanProbe probe(bus_, {});
  orientation_at(0, about_z(10), 0);
  hal::CanFrame corrupt = codec_.encode(ProbeOrientation{about_z(80), 1});
  corrupt.data[0] ^= 0x40;
  bus_.queue.push_back({corrupt, 5'000});
  bus_.queue.push_back({hal::CanFrame{.id = 0x101, .length = 3}, 6'000});
  const auto pose = probe.latest(7'000);
  EXPECT_LT(pose->orientation.angularDistance(about_z(10)), 1e-4);
  EXPECT_EQ(probe.counters().refused, 2);
  EXPECT_EQ(probe.counters().bad_checksum, 1);
  EXPECT_EQ(probe.counters().frames, 3);
}

TEST_F(CanProbeTest, DroppedAndRepeatedFramesAreCounted) {
  CanProbe probe(bus_, {});
  orientation_at(0, about_z(1), 10);
  orientation_at(5'000, about_z(2), 11);
  orientation_at(20'000, about_z(5), 14);  // 12 and 13 lost
  orientation_at(20'001, about_z(9), 14);  // a repeat: ignored
  const auto pose = probe.latest(20'100);
  EXPECT_LT(pose->orientation.angularDistance(about_z(5)), 1e-4);
  EXPECT_EQ(probe.counters().missed, 2);
  EXPECT_EQ(probe.counters().duplicates, 1);
  EXPECT_EQ(probe.counters().orientations, 3);
}

TEST_F(CanProbeTest, AnImuFaultOrABusOffIsAFault) {
  CanProbe probe(bus_, {});
  orientation_at(0, about_z(10), 0);
  ProbeStatus status;
  status.error_flags = kImuNotResponding;
  bus_.queue.push_back({codec_.encode(status), 100});
  EXPECT_EQ(probe.latest(200)->health, hal::PoseHealth::kFault);
  ASSERT_TRUE(probe.last_status().has_value());
  status.error_flags = kSupplyLow;  // a warning, not a fault of the pose
  bus_.queue.push_back({codec_.encode(status), 300});
  EXPECT_EQ(probe.latest(400)->health, hal::PoseHealth::kOk);
  bus_.stats_.state = hal::CanBusState::kBusOff;
  EXPECT_EQ(probe.latest(500)->health, hal::PoseHealth::kFault);
  EXPECT_EQ(probe.status_text(), "can0: bus off");
}

TEST_F(CanProbeTest, HostCommandsGoOutOnTheBus) {
  CanProbe probe(bus_, {});
  EXPECT_TRUE(probe.send_zero(1'000));
  EXPECT_TRUE(probe.request_rate(400, 1'000));
  ASSERT_EQ(bus_.sent.size(), 2u);
  const auto zero = codec_.decode(bus_.sent[0]);
  ASSERT_TRUE(zero.has_value());
  EXPECT_EQ(std::get<HostCommand>(*zero).command, HostCommandKind::kZero);
  const auto rate = codec_.decode(bus_.sent[1]);
  EXPECT_EQ(std::get<HostCommand>(*rate).orientation_rate_hz, 400);
  EXPECT_EQ(std::get<HostCommand>(*rate).sequence, 1);
  bus_.refuse_sends = true;
  EXPECT_FALSE(probe.send_zero(1'000));
  EXPECT_EQ(probe.counters().commands_sent, 2);
  EXPECT_THROW(probe.request_rate(0, 1'000), std::invalid_argument);
  CanProbeSettings bad;
  bad.expected_rate_hz = 0;
  EXPECT_THROW(CanProbe(bus_, bad), std::invalid_argument);
}

TEST_F(CanProbeTest, BoresightMakesTheHeldPoseTheReference) {
  CanProbe probe(bus_, {});
  EXPECT_FALSE(probe.calibrate_mount()) << "nothing to calibrate on yet";
  orientation_at(0, about_z(30), 0);
  probe.latest(100);
  // Held upright in its holder (the reference: identity) while the sensor reads 30° about z.
  ASSERT_TRUE(probe.calibrate_mount());
  EXPECT_LT(probe.mount().angularDistance(about_z(-30)), 1e-4);
  EXPECT_LT(probe.latest(200)->orientation.angularDistance(Eigen::Quaterniond::Identity()), 1e-4);
  orientation_at(5'000, about_z(40), 1);  // turned 10° from the holder
  EXPECT_LT(probe.latest(5'100)->orientation.angularDistance(about_z(10)), 1e-4);
  // Another reference: the holder tilted 90° about x.
  const Eigen::Quaterniond tilted(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  ASSERT_TRUE(probe.calibrate_mount(tilted));
  EXPECT_LT(probe.latest(5'200)->orientation.angularDistance(tilted), 1e-4);
}

TEST_F(CanProbeTest, TheDriverConfiguresStreamsFaultsAndRecovers) {
  using State = CanProbe::State;
  CanProbe probe(bus_, {});
  EXPECT_EQ(probe.state(), State::kReset);
  probe.latest(0);
  EXPECT_EQ(probe.state(), State::kConfigure);
  ASSERT_EQ(bus_.sent.size(), 1u);  // asks for the expected 200 Hz
  const auto request = codec_.decode(bus_.sent[0]);
  ASSERT_TRUE(request.has_value());
  EXPECT_EQ(std::get<HostCommand>(*request).command, HostCommandKind::kSetRate);
  EXPECT_EQ(std::get<HostCommand>(*request).orientation_rate_hz, 200);
  probe.latest(999'999);
  EXPECT_EQ(bus_.sent.size(), 1u);
  probe.latest(1'000'000);  // no confirmation within a second: asks again
  EXPECT_EQ(bus_.sent.size(), 2u);
  EXPECT_EQ(probe.perf().rate_requests, 2);

  ProbeStatus status;
  status.orientation_rate_hz = 100;  // not what was asked: still configuring
  bus_.queue.push_back({codec_.encode(status), 1'100'000});
  probe.latest(1'100'000);
  EXPECT_EQ(probe.state(), State::kConfigure);
  status.orientation_rate_hz = 200;
  bus_.queue.push_back({codec_.encode(status), 1'200'000});
  for (int i = 0; i < 10; ++i) {
    // 5 ms apart, one late by 3 ms.
    orientation_at(1'200'000 + i * 5'000 + (i >= 6 ? 3'000 : 0), about_z(i),
                   static_cast<std::uint8_t>(i));
  }
  probe.latest(1'250'000);
  EXPECT_EQ(probe.state(), State::kStreaming);

  status.error_flags = kImuSelfTestFailed;
  bus_.queue.push_back({codec_.encode(status), 1'300'000});
  probe.latest(1'300'000);
  EXPECT_EQ(probe.state(), State::kFault);
  EXPECT_EQ(probe.perf().faults, 1);
  status.error_flags = 0;
  bus_.queue.push_back({codec_.encode(status), 1'400'000});
  probe.latest(1'400'000);  // cleared: configure again, and ask again
  EXPECT_EQ(probe.state(), State::kConfigure);
  EXPECT_EQ(bus_.sent.size(), 3u);
  bus_.queue.push_back({codec_.encode(status), 1'450'000});
  probe.latest(1'450'000);
  EXPECT_EQ(probe.state(), State::kStreaming);

  const CanProbe::Perf& perf = probe.perf();
  EXPECT_EQ(perf.state_us[static_cast<int>(State::kConfigure)], 1'250'000 + 50'000);
  EXPECT_EQ(perf.state_us[static_cast<int>(State::kStreaming)], 50'000);
  EXPECT_EQ(perf.state_us[static_cast<int>(State::kFault)], 100'000);
  const IntervalHistogram& h = perf.orientation_intervals;
  EXPECT_EQ(h.count(), 9);
  EXPECT_EQ(h.min_us(), 5'000);
  EXPECT_EQ(h.max_us(), 8'000);
  EXPECT_EQ(h.quantile_us(0.5), 5'100);  // the 5.0–5.1 ms bin's upper edge
  EXPECT_EQ(h.quantile_us(1.0), 8'100);
  EXPECT_NEAR(h.mean_us(), (8 * 5'000 + 8'000) / 9.0, 1e-9);
}

}  // namespace
}  // namespace ultrasim::drivers::probe_can
