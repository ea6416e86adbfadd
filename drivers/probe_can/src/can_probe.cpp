#include "ultrasim/drivers/probe_can/can_probe.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace ultrasim::drivers::probe_can {

void IntervalHistogram::add(std::int64_t interval_us) {
  const auto bin = std::clamp<std::int64_t>(interval_us / kBinUs, 0, kBins - 1);
  ++bins_[static_cast<std::size_t>(bin)];
  min_us_ = count_ == 0 ? interval_us : std::min(min_us_, interval_us);
  max_us_ = count_ == 0 ? interval_us : std::max(max_us_, interval_us);
  sum_us_ += interval_us;
  ++count_;
}

std::int64_t IntervalHistogram::quantile_us(double q) const {
  if (count_ == 0) return 0;
  const auto rank = std::max<std::int64_t>(
      1,
      static_cast<std::int64_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(count_))));
  std::int64_t seen = 0;
  for (int b = 0; b < kBins; ++b) {
    seen += bins_[static_cast<std::size_t>(b)];
    if (seen >= rank) return (b + 1) * kBinUs;
  }
  return kBins * kBinUs;
}

CanProbe::CanProbe(hal::CanBus& bus, CanProbeSettings settings)
    : bus_(bus), settings_(std::move(settings)) {
  if (!(settings_.expected_rate_hz > 0.0) || !(settings_.stale_after_periods > 0.0)) {
    throw std::invalid_argument("CanProbe: expected_rate_hz and stale_after_periods must be > 0");
  }
  if (!(settings_.compression_mm_per_n >= 0.0) || !(settings_.max_compression_mm >= 0.0)) {
    throw std::invalid_argument(
        "CanProbe: compression_mm_per_n and max_compression_mm must be >= 0");
  }
  status_text_.reserve(96);
  if (!(std::abs(settings_.mount.norm() - 1.0) < 1e-6)) {
    throw std::invalid_argument("CanProbe: the mount must be a unit quaternion");
  }
}

std::optional<hal::PoseSample> CanProbe::latest(hal::TimestampUs now_us) {
  hal::ReceivedCanFrame received;
  while (bus_.receive(received)) {
    ++counters_.frames;
    const auto decoded = codec_.decode(received.frame);
    if (!decoded) {
      ++counters_.refused;
      counters_.bad_checksum += decoded.error() == DecodeError::kBadChecksum;
      counters_.non_unit += decoded.error() == DecodeError::kNonUnitQuaternion;
      continue;
    }
    if (const auto* o = std::get_if<ProbeOrientation>(&*decoded)) {
      const auto step = sequences_.observe(received.frame.id, o->sequence);
      counters_.missed += step.missed;
      counters_.duplicates += step.duplicate;
      if (step.duplicate) continue;
      ++counters_.orientations;
      if (pose_) perf_.orientation_intervals.add(received.timestamp_us - pose_->timestamp_us);
      hal::PoseSample sample;
      sample.timestamp_us = received.timestamp_us;
      sample.sequence = ++sample_sequence_;
      sensor_ = o->orientation;
      sample.orientation = (sensor_ * settings_.mount).normalized();
      pose_ = sample;
    } else if (const auto* s = std::get_if<ProbeStatus>(&*decoded)) {
      status_ = *s;
    } else if (const auto* in = std::get_if<ProbeInput>(&*decoded)) {
      input_ = *in;
    }
  }
  if (!pose_) {
    status_text_.assign(settings_.name).append(": waiting for the probe");
    advance_state(now_us, std::nullopt);
    return std::nullopt;
  }
  hal::PoseSample out = *pose_;
  // Pressed in along the beam by the newest compression input.
  const double force_n = input_ ? input_->compression_force_n : 0.0;
  const double press_mm =
      std::min(settings_.compression_mm_per_n * force_n, settings_.max_compression_mm);
  out.position_mm = settings_.position_mm + out.orientation * Eigen::Vector3d(0.0, 0.0, press_mm);
  out.health = health(now_us);
  describe(now_us, out.health);
  const bool stale = out.health == hal::PoseHealth::kStale;
  counters_.stale_events += stale && !was_stale_;
  was_stale_ = stale;
  advance_state(now_us, out.health);
  return out;
}

void CanProbe::describe(hal::TimestampUs now_us, hal::PoseHealth pose_health) {
  status_text_.clear();
  if (pose_health == hal::PoseHealth::kOk) return;
  if (bus_.stats().state == hal::CanBusState::kBusOff) {
    status_text_.append(settings_.name).append(": bus off");
  } else if (pose_health == hal::PoseHealth::kFault) {
    status_text_.append(settings_.name).append(": probe reports an IMU fault");
  } else {
    const auto ms = static_cast<long long>((now_us - pose_->timestamp_us) / 1000);
    char text[64];
    std::snprintf(text, sizeof text, ": no orientation for %lld ms", ms);
    status_text_.append(settings_.name).append(text);
  }
}

int CanProbe::requested_rate_hz() const {
  return std::clamp(static_cast<int>(std::lround(settings_.expected_rate_hz)), 1, 1000);
}

void CanProbe::enter(State next) {
  // advance_state() has accounted the time up to now to the state being left.
  state_ = next;
  perf_.faults += next == State::kFault;
}

void CanProbe::advance_state(hal::TimestampUs now_us, std::optional<hal::PoseHealth> health) {
  constexpr hal::TimestampUs kRequestAgainUs = 1'000'000;
  // Account the time spent so far in the current state.
  if (state_since_us_ >= 0) {
    perf_.state_us[static_cast<std::size_t>(state_)] += now_us - state_since_us_;
  }
  state_since_us_ = now_us;
  const bool faulty =
      health == hal::PoseHealth::kFault || bus_.stats().state == hal::CanBusState::kBusOff;
  if (state_ != State::kFault && state_ != State::kReset && faulty) {
    enter(State::kFault);
    return;
  }
  if (state_ == State::kFault && !faulty) {
    last_request_us_ = -1;
    status_.reset();  // the next status must confirm the rate again
    enter(State::kConfigure);
  }
  if (state_ == State::kReset) enter(State::kConfigure);
  if (state_ != State::kConfigure) return;
  // The probe reports its rate in steps of 4 Hz.
  if (status_ && std::abs(status_->orientation_rate_hz - requested_rate_hz()) <= 4 && !faulty) {
    enter(State::kStreaming);
  } else if (last_request_us_ < 0 || now_us - last_request_us_ >= kRequestAgainUs) {
    last_request_us_ = now_us;
    ++perf_.rate_requests;
    request_rate(requested_rate_hz(), now_us + 10'000);
  }
}

hal::PoseHealth CanProbe::health(hal::TimestampUs now_us) const {
  if (bus_.stats().state == hal::CanBusState::kBusOff) return hal::PoseHealth::kFault;
  if (status_ && (status_->error_flags & (kImuNotResponding | kImuSelfTestFailed)) != 0) {
    return hal::PoseHealth::kFault;
  }
  const double rate_hz = status_ && status_->orientation_rate_hz > 0
                             ? static_cast<double>(status_->orientation_rate_hz)
                             : settings_.expected_rate_hz;
  const double stale_after_us = settings_.stale_after_periods * 1e6 / rate_hz;
  if (static_cast<double>(now_us - pose_->timestamp_us) > stale_after_us) {
    return hal::PoseHealth::kStale;
  }
  return hal::PoseHealth::kOk;
}

bool CanProbe::calibrate_mount(const Eigen::Quaterniond& reference) {
  if (!pose_) return false;
  settings_.mount = (sensor_.conjugate() * reference.normalized()).normalized();
  pose_->orientation = (sensor_ * settings_.mount).normalized();
  return true;
}

bool CanProbe::send(const HostCommand& command, hal::TimestampUs deadline_us) {
  HostCommand c = command;
  c.sequence = command_sequence_;
  if (!bus_.send(codec_.encode(c), deadline_us)) return false;
  ++command_sequence_;
  ++counters_.commands_sent;
  return true;
}

bool CanProbe::send_zero(hal::TimestampUs deadline_us) {
  return send({HostCommandKind::kZero, 0, 0}, deadline_us);
}

bool CanProbe::request_rate(int rate_hz, hal::TimestampUs deadline_us) {
  if (rate_hz < 1 || rate_hz > 1000) {
    throw std::invalid_argument("CanProbe::request_rate: " + std::to_string(rate_hz) +
                                " Hz is outside 1..1000");
  }
  return send({HostCommandKind::kSetRate, rate_hz, 0}, deadline_us);
}

}  // namespace ultrasim::drivers::probe_can
