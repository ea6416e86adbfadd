#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/hal/can_bus.hpp"

namespace ultrasim::tools {

// The probe's firmware as the protocol describes it (docs/probe-can.md), for bring-up without
// hardware and for testing the host side on a real bus: it streams orientation at the rate last
// asked for (200 Hz at power-up), its status at 10 Hz and at once when asked, its buttons and
// compression at 50 Hz, and zeroes its orientation on the zero command. The motion: turning
// about the beam at 30°/s with a slow rock, the compression ramping to 5 N and back each 4 s.
// Pure: time and frames in, frames out.
class SimulatedProbeFirmware {
 public:
  // A command from the host (frames of other ids are ignored; bad ones are counted).
  void receive(const hal::CanFrame& frame);
  // The frames due by now_us (µs, the caller's clock), appended to `out`.
  void step(std::int64_t now_us, std::vector<hal::CanFrame>& out);

  int orientation_rate_hz() const { return rate_hz_; }
  std::int64_t commands_received() const { return commands_; }
  std::int64_t commands_refused() const { return refused_; }

 private:
  Eigen::Quaterniond sensor_at(std::int64_t now_us) const;

  drivers::probe_can::ProbeCodec codec_;
  int rate_hz_ = 200;
  bool status_requested_ = false;
  std::int64_t next_orientation_us_ = -1, next_status_us_ = -1, next_input_us_ = -1;
  Eigen::Quaterniond zero_ = Eigen::Quaterniond::Identity();  // the tare: sensor → reported
  bool zero_requested_ = false;
  std::uint8_t orientation_seq_ = 0, status_seq_ = 0, input_seq_ = 0;
  std::int64_t commands_ = 0, refused_ = 0;
};

}  // namespace ultrasim::tools
