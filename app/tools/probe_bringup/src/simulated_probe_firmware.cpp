#include "ultrasim/tools/simulated_probe_firmware.hpp"

#include <cmath>
#include <variant>

namespace ultrasim::tools {

namespace pc = drivers::probe_can;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::int64_t kStatusPeriodUs = 100'000;
constexpr std::int64_t kInputPeriodUs = 20'000;

}  // namespace

void SimulatedProbeFirmware::receive(const hal::CanFrame& frame) {
  const auto decoded = codec_.decode(frame);
  if (!decoded) {
    refused_ += decoded.error() != pc::DecodeError::kUnknownId;
    return;
  }
  const auto* command = std::get_if<pc::HostCommand>(&*decoded);
  if (command == nullptr) return;
  ++commands_;
  switch (command->command) {
    case pc::HostCommandKind::kZero:
      zero_requested_ = true;
      break;
    case pc::HostCommandKind::kSetRate:
      rate_hz_ = command->orientation_rate_hz;
      status_requested_ = true;  // confirm the new rate at once
      break;
    case pc::HostCommandKind::kRequestStatus:
      status_requested_ = true;
      break;
  }
}

Eigen::Quaterniond SimulatedProbeFirmware::sensor_at(std::int64_t now_us) const {
  const double t = static_cast<double>(now_us) * 1e-6;
  return Eigen::Quaterniond(Eigen::AngleAxisd(30.0 * kPi / 180.0 * t, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(0.2 * std::sin(t), Eigen::Vector3d::UnitX()));
}

void SimulatedProbeFirmware::step(std::int64_t now_us, std::vector<hal::CanFrame>& out) {
  if (next_orientation_us_ < 0) next_orientation_us_ = next_status_us_ = next_input_us_ = now_us;
  if (zero_requested_) {
    zero_ = sensor_at(now_us).conjugate();
    zero_requested_ = false;
  }
  const std::int64_t period_us = 1'000'000 / std::max(rate_hz_, 1);
  // A late caller gets the newest of each message, not a burst of stale ones.
  if (now_us >= next_orientation_us_) {
    out.push_back(codec_.encode(
        pc::ProbeOrientation{(zero_ * sensor_at(now_us)).normalized(), orientation_seq_++}));
    next_orientation_us_ = std::max(next_orientation_us_ + period_us, now_us);
  }
  if (now_us >= next_status_us_ || status_requested_) {
    pc::ProbeStatus status;
    status.firmware_major = 1;
    status.firmware_minor = 2;
    status.calibration_system = status.calibration_gyro = status.calibration_accel =
        status.calibration_mag = 3;
    status.orientation_rate_hz = rate_hz_;
    status.sequence = status_seq_++;
    out.push_back(codec_.encode(status));
    if (now_us >= next_status_us_) next_status_us_ += kStatusPeriodUs;
    status_requested_ = false;
  }
  if (now_us >= next_input_us_) {
    pc::ProbeInput input;
    const double phase = std::fmod(static_cast<double>(now_us) * 1e-6, 4.0) / 2.0;  // 0..2
    input.compression_force_n = 5.0 * (phase < 1.0 ? phase : 2.0 - phase);
    input.sequence = input_seq_++;
    out.push_back(codec_.encode(input));
    next_input_us_ = std::max(next_input_us_ + kInputPeriodUs, now_us);
  }
}

}  // namespace ultrasim::tools
