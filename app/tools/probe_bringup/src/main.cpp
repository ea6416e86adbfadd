// ultrasim-probe-bringup: the probe's CAN traffic for the engineer commissioning it. Reads a
// candump -l log through the replay driver (the same hal::CanBus the kiosk reads) and reports
// every decoded frame and, per message, rate, arrival intervals and missed frames; writes a demo
// log of the protocol (our encoder) for other tools to read.

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/can_replay/replay_bus.hpp"
#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/tools/probe_traffic.hpp"

namespace {

using namespace ultrasim;
namespace pc = drivers::probe_can;
namespace cr = drivers::can_replay;

int replay(const std::string& path, bool print_frames) {
  hal::ManualClock clock;
  cr::ReplayBus bus(cr::read_candump_log(path), clock);
  tools::ProbeTraffic traffic;
  hal::ReceivedCanFrame received;
  while (!bus.finished()) {
    while (bus.receive(received)) {
      const auto decoded = traffic.add(received);
      if (!print_frames) continue;
      if (decoded) {
        std::cout << tools::message_json(received, *decoded) << '\n';
      } else {
        std::printf("{\"t_us\": %lld, \"id\": %u, \"error\": \"%s\"}\n",
                    static_cast<long long>(received.timestamp_us), received.frame.id,
                    std::string(pc::describe(decoded.error())).c_str());
      }
    }
    clock.advance_us(100'000);  // frames carry their due time, however far the clock jumps
  }
  std::cout << traffic.json() << std::endl;
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
  std::string replay_path, demo_path;
  bool frames = false;
  double seconds = 1.0;
  app.add_option("--replay", replay_path,
                 "candump -l log to decode: one JSON summary line (rate, intervals, missed "
                 "frames per message; refused frames by reason)");
  app.add_flag("--frames", frames, "with --replay: every decoded frame as a JSON line first");
  app.add_option("--write-demo", demo_path,
                 "write a demo log of the protocol: the probe turning at 30 deg/s, 200 Hz");
  app.add_option("--seconds", seconds, "length of --write-demo's log")
      ->check(CLI::Range(0.01, 3600.0));
  CLI11_PARSE(app, argc, argv);
  try {
    if (!demo_path.empty()) return write_demo(demo_path, seconds);
    if (!replay_path.empty()) return replay(replay_path, frames);
    std::cerr << app.help();
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-probe-bringup: " << e.what() << '\n';
    return 1;
  }
}
