// The SocketCAN driver in a real Linux kernel (run by tests/vm/run_in_vm.sh in a QEMU VM with
// vcan0): frames from can-utils' cansend arrive with kernel timestamps, ours reach candump, a
// probe stream played by canplayer becomes poses (with the frame-to-pose latency measured), and
// a receive queue that overflows is counted.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>
#include <vector>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/drivers/probe_can/can_probe.hpp"
#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"

namespace ultrasim::drivers::socketcan {
namespace {

using namespace std::chrono_literals;

class SocketCanVmTest : public ::testing::Test {
 protected:
  // Polls until a frame arrives or `timeout` passes.
  static bool receive_within(SocketCanBus& bus, hal::ReceivedCanFrame& out,
                             std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      if (bus.receive(out)) return true;
      std::this_thread::sleep_for(100us);
    }
    return false;
  }
  posix::MonotonicClock clock_;
};

TEST_F(SocketCanVmTest, AMissingInterfaceIsNamedInTheError) {
  try {
    SocketCanBus bus("nocan7", clock_);
    FAIL() << "opened an interface that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("nocan7"), std::string::npos) << e.what();
  }
}

TEST_F(SocketCanVmTest, FramesFromCansendArriveWithKernelTimestamps) {
  SocketCanBus bus("vcan0", clock_);
  const hal::TimestampUs before = clock_.now_us();
  ASSERT_EQ(std::system("cansend vcan0 101#0011223344556677"), 0);
  ASSERT_EQ(std::system("cansend vcan0 18FF0102#AA"), 0);
  hal::ReceivedCanFrame got;
  ASSERT_TRUE(receive_within(bus, got, 2000ms));
  const hal::TimestampUs after = clock_.now_us();
  EXPECT_EQ(got.frame.id, 0x101u);
  EXPECT_FALSE(got.frame.extended);
  EXPECT_EQ(got.frame.length, 8);
  EXPECT_EQ(got.frame.data[7], 0x77);
  EXPECT_GE(got.timestamp_us, before - 2000);  // wall-to-monotonic mapping: within the call
  EXPECT_LE(got.timestamp_us, after);
  ASSERT_TRUE(receive_within(bus, got, 2000ms));
  EXPECT_TRUE(got.frame.extended);
  EXPECT_EQ(got.frame.id, 0x18FF0102u);
  EXPECT_EQ(bus.stats().rx_frames, 2u);
  EXPECT_EQ(bus.stats().state, hal::CanBusState::kErrorActive);
}

TEST_F(SocketCanVmTest, OurFramesReachCandump) {
  SocketCanBus bus("vcan0", clock_);
  // candump in the background, logging the first frame it sees.
  ASSERT_EQ(std::system("(timeout 10 candump -L -n 1 vcan0 > candump.log) & sleep 0.5"), 0);
  const probe_can::ProbeCodec codec;
  const hal::CanFrame sent = codec.encode(probe_can::ProbeOrientation{
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())), 42});
  ASSERT_TRUE(bus.send(sent, clock_.now_us() + 100'000));
  std::vector<can_replay::CandumpRecord> records;
  for (int i = 0; i < 100 && records.empty(); ++i) {
    std::this_thread::sleep_for(50ms);
    records = can_replay::read_candump_log("candump.log");
  }
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].frame, sent);
  EXPECT_EQ(records[0].interface, "vcan0");
  const auto decoded = codec.decode(records[0].frame);
  ASSERT_TRUE(decoded.has_value());
  EXPECT_EQ(std::get<probe_can::ProbeOrientation>(*decoded).sequence, 42);
  EXPECT_EQ(bus.stats().tx_frames, 1u);
}

TEST_F(SocketCanVmTest, AProbeStreamFromCanplayerBecomesPosesAndItsLatencyIsMeasured) {
  // 400 orientations at 200 Hz (2 s), played by can-utils' canplayer at the log's pace.
  const probe_can::ProbeCodec codec;
  {
    std::ofstream log("probe.log");
    for (int i = 0; i < 400; ++i) {
      const Eigen::Quaterniond q(Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d::UnitZ()));
      log << can_replay::format_candump_line(
                 {1'000'000 + i * 5'000, "can0",
                  codec.encode(probe_can::ProbeOrientation{q, static_cast<std::uint8_t>(i)})})
          << '\n';
    }
  }
  SocketCanBus bus("vcan0", clock_);
  probe_can::CanProbe probe(bus, {});
  ASSERT_EQ(std::system("canplayer -I probe.log vcan0=can0 &"), 0);
  std::vector<std::int64_t> latency_us;
  std::uint32_t last_sequence = 0;
  const auto until = std::chrono::steady_clock::now() + 20s;
  while (probe.counters().orientations < 400 && std::chrono::steady_clock::now() < until) {
    const auto pose = probe.latest(clock_.now_us());
    if (pose && pose->sequence != last_sequence) {
      // From the kernel's receive stamp to the pose being available here.
      latency_us.push_back(clock_.now_us() - pose->timestamp_us);
      last_sequence = pose->sequence;
    }
  }
  EXPECT_EQ(probe.counters().orientations, 400);
  EXPECT_EQ(probe.counters().missed, 0);
  EXPECT_EQ(probe.counters().refused, 0);
  const auto pose = probe.latest(clock_.now_us());
  ASSERT_TRUE(pose.has_value());
  EXPECT_LT(pose->orientation.angularDistance(
                Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * 399, Eigen::Vector3d::UnitZ()))),
            1e-3);
  ASSERT_FALSE(latency_us.empty());
  std::sort(latency_us.begin(), latency_us.end());
  const auto at = [&](double q) {
    return latency_us[std::min(
        latency_us.size() - 1,
        static_cast<std::size_t>(q * static_cast<double>(latency_us.size())))];
  };
  // Reported, not asserted (times in an emulated VM): docs/benchmarks.md records them.
  std::printf(
      "CAN frame to pose (kernel stamp -> CanProbe::latest), %zu poses: p50 %lld us, p99 "
      "%lld us, max %lld us\n",
      latency_us.size(), static_cast<long long>(at(0.5)), static_cast<long long>(at(0.99)),
      static_cast<long long>(latency_us.back()));
}

TEST_F(SocketCanVmTest, TheBringUpToolListensLiveThroughTheProbeDriver) {
  // One second of a probe: status at 10 Hz saying 200 Hz, orientations at 200 Hz.
  const probe_can::ProbeCodec codec;
  {
    std::ofstream log("live.log");
    for (int i = 0; i < 200; ++i) {
      const std::int64_t t = 1'000'000 + i * 5'000;
      if (i % 20 == 0) {
        probe_can::ProbeStatus status;
        status.orientation_rate_hz = 200;
        status.sequence = static_cast<std::uint8_t>(i / 20);
        log << can_replay::format_candump_line({t, "can0", codec.encode(status)}) << '\n';
      }
      log << can_replay::format_candump_line(
                 {t + 100, "can0",
                  codec.encode(probe_can::ProbeOrientation{Eigen::Quaterniond::Identity(),
                                                           static_cast<std::uint8_t>(i)})})
          << '\n';
    }
  }
  std::remove("bringup.json");
  ASSERT_EQ(std::system("(" ULTRASIM_BRINGUP_EXE
                        " --interface vcan0 --seconds 3 > bringup.partial && mv bringup.partial "
                        "bringup.json) & sleep 0.5"),
            0);
  ASSERT_EQ(std::system("canplayer -I live.log vcan0=can0"), 0);
  std::string summary;
  for (int i = 0; i < 200 && summary.empty(); ++i) {
    std::this_thread::sleep_for(50ms);
    std::ifstream in("bringup.json");
    std::getline(in, summary);
  }
  ASSERT_FALSE(summary.empty()) << "the tool wrote no summary";
  std::printf("bring-up summary: %s\n", summary.c_str());
  EXPECT_NE(summary.find("\"ProbeOrientation\": {\"frames\": 200"), std::string::npos);
  EXPECT_NE(summary.find("\"state\": \"streaming\""), std::string::npos);
  EXPECT_NE(summary.find("\"missed\": 0"), std::string::npos);
  EXPECT_NE(summary.find("\"rx_frames\": 210"), std::string::npos);
}

// Bring-up without hardware: one tool plays the probe's firmware on vcan0, the other configures
// it through the probe driver, re-rates it to 100 Hz and times 100 status requests end to end.
TEST_F(SocketCanVmTest, TheBringUpToolTimesRoundTripsToASimulatedProbe) {
  std::remove("firmware.json");
  std::remove("host.json");
  ASSERT_EQ(std::system("(" ULTRASIM_BRINGUP_EXE
                        " --simulate-probe --interface vcan0 --seconds 6 > firmware.partial && "
                        "mv firmware.partial firmware.json) & sleep 0.3"),
            0);
  ASSERT_EQ(std::system(ULTRASIM_BRINGUP_EXE " --interface vcan0 --seconds 1 --rate 100 "
                                             "--round-trips 100 > host.json"),
            0);
  std::string host;
  std::getline(std::ifstream("host.json") >> std::ws, host);
  std::printf("host: %s\n", host.c_str());
  EXPECT_NE(host.find("\"state\": \"streaming\""), std::string::npos);
  EXPECT_NE(host.find("\"round_trip\": {\"count\": 100, \"lost\": 0"), std::string::npos);
  // Every request answered; the median answers well inside a 100 Hz stream's period. The tail is
  // the emulated VM's scheduling beside the rest of the suite (p99 584 us on a quiet host, 8.5 ms
  // on a busy CI host for the same code), so it is reported, not bounded: docs/benchmarks.md.
  const auto p50_at = host.find("\"p50_us\": ", host.find("\"round_trip\""));
  ASSERT_NE(p50_at, std::string::npos);
  const long p50_us = std::stol(host.substr(p50_at + 10));
  EXPECT_LT(p50_us, 5'000) << "status request to answer, p50";
  std::string firmware;
  for (int i = 0; i < 200 && firmware.empty(); ++i) {
    std::this_thread::sleep_for(50ms);
    std::ifstream in("firmware.json");
    std::getline(in, firmware);
  }
  std::printf("firmware: %s\n", firmware.c_str());
  EXPECT_NE(firmware.find("\"rate_hz\": 100"), std::string::npos);
  EXPECT_NE(firmware.find("\"commands_refused\": 0"), std::string::npos);
}

TEST_F(SocketCanVmTest, AnOverflowingReceiveQueueIsCounted) {
  SocketCanBus receiver("vcan0", clock_);
  SocketCanBus sender("vcan0", clock_);
  hal::CanFrame frame;
  frame.id = 0x123;
  frame.length = 8;
  int sent = 0;
  for (int i = 0; i < 5000; ++i) sent += sender.send(frame, clock_.now_us() + 1'000'000);
  ASSERT_GT(sent, 1000);
  hal::ReceivedCanFrame got;
  int received = 0;
  while (receiver.receive(got)) ++received;
  EXPECT_LT(received, sent) << "the socket's queue held every frame: nothing to count";
  // The kernel's drop count comes with each frame queued after the drops: the next one.
  ASSERT_TRUE(sender.send(frame, clock_.now_us() + 1'000'000));
  ASSERT_TRUE(receive_within(receiver, got, 2000ms));
  EXPECT_EQ(receiver.stats().rx_overflows, static_cast<std::uint64_t>(sent - received));
  std::printf("overflow: %d sent, %d received, %llu counted dropped\n", sent, received,
              static_cast<unsigned long long>(receiver.stats().rx_overflows));
}

}  // namespace
}  // namespace ultrasim::drivers::socketcan
