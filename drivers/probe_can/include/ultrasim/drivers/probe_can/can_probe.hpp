#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/probe_can/sequence_tracker.hpp"
#include "ultrasim/hal/can_bus.hpp"
#include "ultrasim/hal/pose_source.hpp"

namespace ultrasim::drivers::probe_can {

struct CanProbeSettings {
  std::string name = "can0";  // shown in the stats overlay and logs
  // The orientation rate the probe is expected to send when no status has said otherwise.
  double expected_rate_hz = 200.0;
  // No orientation for this many periods: the pose is stale (the last good one is kept).
  double stale_after_periods = 3.0;
  // The IMU gives orientation only (3 DOF): where the probe's face is, in case space, mm.
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  // Sensor to probe (mount calibration): probe orientation = sensor orientation × mount.
  Eigen::Quaterniond mount = Eigen::Quaterniond::Identity();
};

// The mock probe on a CAN bus as a pose source. Each latest() drains the bus, decodes every
// frame and keeps the newest orientation that decoded; frames that do not decode are counted by
// reason and never become a pose. Health: kOk while orientations arrive; kStale once none has
// for stale_after_periods of the expected period (the probe's status sets the rate); kFault
// while the probe reports its IMU not responding or failing its self-test, or the bus is off.
// A stale or faulty sample still carries the last good orientation (never garbage); consumers
// use only kOk ones. Non-blocking; the frame thread calls it.
class CanProbe final : public hal::PoseSource {
 public:
  struct Counters {
    std::int64_t frames = 0;         // received
    std::int64_t orientations = 0;   // decoded orientations
    std::int64_t missed = 0;         // orientations missing by their sequence counter
    std::int64_t duplicates = 0;     // an orientation's sequence repeated
    std::int64_t refused = 0;        // frames that did not decode (any reason)
    std::int64_t bad_checksum = 0;   // of those, checksum mismatches
    std::int64_t non_unit = 0;       // of those, orientations that are no unit quaternion
    std::int64_t stale_events = 0;   // times the pose went from fresh to stale
    std::int64_t commands_sent = 0;  // host commands the bus took
  };

  // `bus` must outlive the probe. Throws std::invalid_argument for a rate or stale period that
  // is not > 0, or a mount that is not a unit quaternion.
  CanProbe(hal::CanBus& bus, CanProbeSettings settings);

  std::optional<hal::PoseSample> latest(hal::TimestampUs now_us) override;
  std::string_view name() const override { return settings_.name; }

  const Counters& counters() const { return counters_; }
  const std::optional<ProbeStatus>& last_status() const { return status_; }
  std::optional<ProbeInput> last_input() const { return input_; }

  // Host commands, sent with a deadline: zero (tare: the probe's current orientation becomes
  // identity) and the orientation rate. False when the bus did not take the frame.
  bool send_zero(hal::TimestampUs deadline_us);
  bool request_rate(int rate_hz, hal::TimestampUs deadline_us);

 private:
  bool send(const HostCommand& command, hal::TimestampUs deadline_us);
  hal::PoseHealth health(hal::TimestampUs now_us) const;

  hal::CanBus& bus_;
  CanProbeSettings settings_;
  ProbeCodec codec_;
  SequenceTracker sequences_;
  Counters counters_;
  std::optional<hal::PoseSample> pose_;  // the newest good orientation, as a sample
  std::optional<ProbeStatus> status_;
  std::optional<ProbeInput> input_;
  bool was_stale_ = false;
  std::uint8_t command_sequence_ = 0;
  std::uint32_t sample_sequence_ = 0;
};

}  // namespace ultrasim::drivers::probe_can
