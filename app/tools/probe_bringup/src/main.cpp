// ultrasim-probe-bringup: the probe's CAN traffic for the engineer commissioning it. Reads a
// candump -l log through the replay driver, or a live SocketCAN interface, through the same probe
// driver the kiosk uses, and reports every decoded frame and, per message, rate, arrival
// intervals and missed frames, with the driver's state, perf counters and jitter histogram and
// the bus's stats; writes a demo log of the protocol (our encoder) for other tools to read.

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>
#include <thread>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/can_replay/replay_bus.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/drivers/probe_can/can_probe.hpp"
#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/tools/probe_traffic.hpp"

namespace {

using namespace ultrasim;
namespace pc = drivers::probe_can;
namespace cr = drivers::can_replay;

// `traffic`: the session's ProbeTraffic, which names the messages after the protocol's database.
void print_frame(void* traffic, const hal::ReceivedCanFrame& received,
                 const std::expected<pc::ProbeMessage, pc::DecodeError>& decoded) {
  if (decoded) {
    std::cout << static_cast<const tools::ProbeTraffic*>(traffic)->message_json(received, *decoded)
              << '\n';
  } else {
    std::printf("{\"t_us\": %lld, \"id\": %u, \"error\": \"%s\"}\n",
                static_cast<long long>(received.timestamp_us), received.frame.id,
                std::string(pc::describe(decoded.error())).c_str());
  }
}

// The probe driver reads the bus through a tap that accounts (and prints) every frame; the
// summary is the traffic's and the driver's view.
struct Session {
  Session(hal::CanBus& bus, const std::string& name, int rate_hz, bool print_frames)
      : tap(bus, traffic), probe(tap, settings(name, rate_hz)) {
    if (print_frames) tap.on_frame(&print_frame, &traffic);
  }
  static pc::CanProbeSettings settings(const std::string& name, int rate_hz) {
    pc::CanProbeSettings s;
    s.name = name;
    s.expected_rate_hz = rate_hz;
    return s;
  }
  // With `boresight`: the mount that makes the last orientation identity, for the kiosk's
  // settings (the probe held upright in its holder at the end of the session).
  void print_summary(const hal::CanBusStats& bus, bool boresight) {
    std::cout << "{\"traffic\": " << traffic.json()
              << ", \"driver\": " << tools::driver_json(probe, bus);
    if (boresight) {
      if (probe.calibrate_mount()) {
        const Eigen::Quaterniond& m = probe.mount();
        std::printf(", \"mount_wxyz\": [%.9f, %.9f, %.9f, %.9f]", m.w(), m.x(), m.y(), m.z());
        std::fflush(stdout);
      } else {
        std::cout << ", \"mount_wxyz\": null";
      }
    }
    std::cout << '}' << std::endl;
  }
  tools::ProbeTraffic traffic;
  tools::TrafficTap tap;
  pc::CanProbe probe;
};

int replay(const std::string& path, int rate_hz, bool print_frames, bool boresight) {
  hal::ManualClock clock;
  cr::ReplayBus bus(cr::read_candump_log(path), clock);
  Session session(bus, path, rate_hz, print_frames);
  while (!bus.finished()) {
    session.probe.latest(clock.now_us());
    clock.advance_us(1'000);  // frames carry their due time: the driver sees the log's pace
  }
  session.probe.latest(clock.now_us());
  session.print_summary(bus.stats(), boresight);
  return 0;
}

int live(const std::string& interface, double seconds, int rate_hz, bool zero, bool print_frames,
         bool boresight) {
  drivers::posix::MonotonicClock clock;
  drivers::socketcan::SocketCanBus bus(interface, clock);
  Session session(bus, interface, rate_hz, print_frames);
  const hal::TimestampUs start = clock.now_us();
  if (zero && !session.probe.send_zero(start + 10'000)) {
    std::cerr << "ultrasim-probe-bringup: the zero command was not sent\n";
  }
  while (static_cast<double>(clock.now_us() - start) < seconds * 1e6) {
    session.probe.latest(clock.now_us());
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  session.print_summary(bus.stats(), boresight);
  return 0;
}

// A probe turning about its beam axis at 30°/s: orientation at 200 Hz, status at 10 Hz, input
// at 50 Hz with the compression force ramping up.
int write_demo(const std::string& path, double seconds) {
  const pc::ProbeCodec codec;
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  const std::int64_t start_us = 1'700'000'000'000'000;
  std::uint8_t orientation_seq = 0, status_seq = 0, input_seq = 0;
  const auto total_us = static_cast<std::int64_t>(seconds * 1e6);
  for (std::int64_t t = 0; t < total_us; t += 5'000) {
    const double angle = 30.0 * M_PI / 180.0 * static_cast<double>(t) * 1e-6;
    auto write = [&](const pc::ProbeMessage& m, std::int64_t offset_us) {
      out << cr::format_candump_line({start_us + t + offset_us, "can0", codec.encode(m)}) << '\n';
    };
    write(
        pc::ProbeOrientation{Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ())),
                             orientation_seq++},
        0);
    if (t % 20'000 == 0) {
      pc::ProbeInput input;
      input.compression_force_n = 0.5 * static_cast<double>(t) * 1e-6;
      input.sequence = input_seq++;
      write(input, 100);
    }
    if (t % 100'000 == 0) {
      pc::ProbeStatus status;
      status.firmware_major = 1;
      status.firmware_minor = 0;
      status.calibration_system = status.calibration_gyro = status.calibration_accel = 3;
      status.orientation_rate_hz = 200;
      status.sequence = status_seq++;
      write(status, 200);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ultrasim probe bring-up: decode and measure the probe's CAN traffic"};
  std::string replay_path, demo_path, interface;
  bool frames = false, zero = false, boresight = false;
  double seconds = 1.0;
  int rate_hz = 200;
  app.add_option("--replay", replay_path,
                 "candump -l log to decode through the probe driver (replay)");
  app.add_option("--interface", interface,
                 "SocketCAN interface to listen on live (can0, vcan0) for --seconds");
  app.add_flag("--frames", frames, "every decoded frame as a JSON line before the summary");
  app.add_option("--rate", rate_hz, "orientation rate to ask the probe for, Hz")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_flag("--zero", zero, "live: send the zero (tare) command first");
  app.add_flag("--boresight", boresight,
               "mount calibration: with the probe upright in its holder at the end, print the "
               "mount that makes that pose identity (mount_wxyz)");
  app.add_option("--write-demo", demo_path,
                 "write a demo log of the protocol: the probe turning at 30 deg/s, 200 Hz");
  app.add_option("--seconds", seconds, "length of the live session or of --write-demo's log")
      ->check(CLI::Range(0.01, 3600.0));
  CLI11_PARSE(app, argc, argv);
  try {
    if (!demo_path.empty()) return write_demo(demo_path, seconds);
    if (!replay_path.empty()) return replay(replay_path, rate_hz, frames, boresight);
    if (!interface.empty()) return live(interface, seconds, rate_hz, zero, frames, boresight);
    std::cerr << app.help();
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-probe-bringup: " << e.what() << '\n';
    return 1;
  }
}
