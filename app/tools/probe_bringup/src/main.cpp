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
#include <variant>
#include <vector>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/drivers/can_replay/replay_bus.hpp"
#include "ultrasim/drivers/posix/monotonic_clock.hpp"
#include "ultrasim/drivers/probe_can/can_probe.hpp"
#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/tools/probe_traffic.hpp"
#include "ultrasim/tools/round_trip_meter.hpp"
#include "ultrasim/tools/simulated_probe_firmware.hpp"

namespace {

using namespace ultrasim;
namespace pc = drivers::probe_can;
namespace cr = drivers::can_replay;

// What the tap tells about each frame: printed (with --frames), and a status answering a
// round-trip request timed.
struct FrameObserver {
  const tools::ProbeTraffic* traffic = nullptr;  // names the messages after the database
  bool print = false;
  tools::RoundTripMeter round_trips;
};

void observe_frame(void* context, const hal::ReceivedCanFrame& received,
                   const std::expected<pc::ProbeMessage, pc::DecodeError>& decoded) {
  auto& observer = *static_cast<FrameObserver*>(context);
  if (decoded && std::holds_alternative<pc::ProbeStatus>(*decoded)) {
    observer.round_trips.status_received(received.timestamp_us);
  }
  if (!observer.print) return;
  if (decoded) {
    std::cout << observer.traffic->message_json(received, *decoded) << '\n';
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
    observer.traffic = &traffic;
    observer.print = print_frames;
    tap.on_frame(&observe_frame, &observer);
  }
  static pc::CanProbeSettings settings(const std::string& name, int rate_hz) {
    pc::CanProbeSettings s;
    s.name = name;
    s.expected_rate_hz = rate_hz;
    return s;
  }
  // With `boresight`: the mount that makes the last orientation identity, for the kiosk's
  // settings (the probe held upright in its holder at the end of the session).
  void print_summary(const hal::CanBusStats& bus, bool boresight, bool round_trips = false) {
    std::cout << "{\"traffic\": " << traffic.json()
              << ", \"driver\": " << tools::driver_json(probe, bus);
    if (round_trips) std::cout << ", \"round_trip\": " << observer.round_trips.json();
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
  FrameObserver observer;
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

// End-to-end check: `count` status requests 20 ms apart, each timed from its send to the status
// answering it (kernel receive timestamp); 50 ms without an answer counts as lost.
void measure_round_trips(Session& session, const hal::Clock& clock, int count) {
  const pc::ProbeCodec codec;
  pc::HostCommand request;
  request.command = pc::HostCommandKind::kRequestStatus;
  for (int i = 0; i < count; ++i) {
    request.sequence = static_cast<std::uint8_t>(i);
    const hal::TimestampUs sent = clock.now_us();
    session.observer.round_trips.sent(sent);
    if (!session.tap.send(codec.encode(request), sent + 10'000)) {
      session.observer.round_trips.give_up();
      continue;
    }
    while (session.observer.round_trips.waiting() && clock.now_us() - sent < 50'000) {
      session.probe.latest(clock.now_us());
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
    session.observer.round_trips.give_up();  // no-op when answered
    while (clock.now_us() - sent < 20'000) {
      session.probe.latest(clock.now_us());
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
}

// Plays the probe's firmware on a live interface for `seconds` (a peer for the host side).
int simulate_probe(const std::string& interface, double seconds) {
  drivers::posix::MonotonicClock clock;
  drivers::socketcan::SocketCanBus bus(interface, clock);
  tools::SimulatedProbeFirmware firmware;
  std::vector<hal::CanFrame> out;
  std::int64_t sent = 0, refused_by_bus = 0;
  const hal::TimestampUs start = clock.now_us();
  while (static_cast<double>(clock.now_us() - start) < seconds * 1e6) {
    hal::ReceivedCanFrame received;
    while (bus.receive(received)) firmware.receive(received.frame);
    out.clear();
    firmware.step(clock.now_us(), out);
    for (const auto& frame : out) {
      if (bus.send(frame, clock.now_us() + 1'000)) {
        ++sent;
      } else {
        ++refused_by_bus;
      }
    }
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  std::printf(
      "{\"simulated_probe\": {\"frames_sent\": %lld, \"not_sent\": %lld, "
      "\"commands\": %lld, \"commands_refused\": %lld, \"rate_hz\": %d}}\n",
      static_cast<long long>(sent), static_cast<long long>(refused_by_bus),
      static_cast<long long>(firmware.commands_received()),
      static_cast<long long>(firmware.commands_refused()), firmware.orientation_rate_hz());
  return 0;
}

int live(const std::string& interface, double seconds, int rate_hz, bool zero, bool print_frames,
         bool boresight, int round_trips) {
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
  if (round_trips > 0) measure_round_trips(session, clock, round_trips);
  session.print_summary(bus.stats(), boresight, round_trips > 0);
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
  bool frames = false, zero = false, boresight = false, simulate = false;
  int round_trips = 0;
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
  app.add_option("--round-trips", round_trips,
                 "live: after --seconds of listening, time this many status requests from send to "
                 "answer (the end-to-end latency check)")
      ->check(CLI::Range(0, 100000));
  app.add_flag("--simulate-probe", simulate,
               "play the probe's firmware on --interface for --seconds: orientation at the rate "
               "asked for, status, input, answers to commands (a peer without hardware)");
  app.add_option("--seconds", seconds, "length of the live session or of --write-demo's log")
      ->check(CLI::Range(0.01, 3600.0));
  CLI11_PARSE(app, argc, argv);
  try {
    if (!demo_path.empty()) return write_demo(demo_path, seconds);
    if (!replay_path.empty()) return replay(replay_path, rate_hz, frames, boresight);
    if (simulate && !interface.empty()) return simulate_probe(interface, seconds);
    if (!interface.empty()) {
      return live(interface, seconds, rate_hz, zero, frames, boresight, round_trips);
    }
    std::cerr << app.help();
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ultrasim-probe-bringup: " << e.what() << '\n';
    return 1;
  }
}
