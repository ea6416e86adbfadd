#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "ultrasim/drivers/probe_can/probe_protocol.hpp"
#include "ultrasim/drivers/probe_can/sequence_tracker.hpp"
#include "ultrasim/hal/can_bus.hpp"
#include "ultrasim/hal/pose_source.hpp"

namespace ultrasim::drivers::probe_can {

// Arrival intervals of a periodic message, in 100 µs bins up to 50 ms (longer ones in the last):
// the jitter a bring-up engineer looks at. Fixed size, no allocation.
class IntervalHistogram {
 public:
  static constexpr std::int64_t kBinUs = 100;
  static constexpr int kBins = 500;

  void add(std::int64_t interval_us);
  std::int64_t count() const { return count_; }
  std::int64_t min_us() const { return count_ > 0 ? min_us_ : 0; }
  std::int64_t max_us() const { return max_us_; }
  double mean_us() const { return count_ > 0 ? static_cast<double>(sum_us_) / count_ : 0.0; }
  // The upper edge of the bin holding quantile q in [0, 1] (nearest rank); 0 when empty.
  std::int64_t quantile_us(double q) const;
  const std::array<std::int64_t, kBins>& bins() const { return bins_; }

 private:
  std::array<std::int64_t, kBins> bins_{};
  std::int64_t count_ = 0, sum_us_ = 0, min_us_ = 0, max_us_ = 0;
};

struct CanProbeSettings {
  std::string name = "can0";  // shown in the stats overlay and logs
  // The orientation rate the probe is expected to send when no status has said otherwise.
  double expected_rate_hz = 200.0;
  // No orientation for this many periods: the pose is stale (the last good one is kept).
  double stale_after_periods = 3.0;
  // The IMU gives orientation only (3 DOF): where the probe's face is, in case space, mm.
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  // The probe's compression input (a force sensor in the handle) presses the face in along its
  // beam (+z of the probe frame): this many mm per newton, up to max_compression_mm. A
  // displacement the simulation imposes, as the published compression buttons did.
  double compression_mm_per_n = 0.0;
  double max_compression_mm = 20.0;
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
  // The driver's state, PX4 style: kReset until the first latest(); kConfigure while it asks the
  // probe for the expected rate and waits for a status confirming it (asking again every second);
  // kStreaming once confirmed; kFault while the pose's health is kFault (IMU flags, bus off), then
  // kConfigure again when that clears.
  enum class State : std::uint8_t { kReset, kConfigure, kStreaming, kFault };

  // Perf counters: time in each state (indexed by State), entries into kFault, rate requests,
  // and the orientation arrival intervals by kernel timestamp (jitter).
  struct Perf {
    std::array<std::int64_t, 4> state_us{};
    std::int64_t faults = 0;
    std::int64_t rate_requests = 0;
    IntervalHistogram orientation_intervals;
  };

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
  // is not > 0, a negative compression scale or limit, or a mount that is not a unit
  // quaternion.
  CanProbe(hal::CanBus& bus, CanProbeSettings settings);

  std::optional<hal::PoseSample> latest(hal::TimestampUs now_us) override;
  std::string_view name() const override { return settings_.name; }
  // While the pose is not fresh: bus off, the IMU's fault, or how long nothing has come.
  std::string_view status_text() const override { return status_text_; }

  const Counters& counters() const { return counters_; }
  State state() const { return state_; }
  const Perf& perf() const { return perf_; }
  const std::optional<ProbeStatus>& last_status() const { return status_; }
  std::optional<ProbeInput> last_input() const { return input_; }

  // Mount calibration (boresight): with the probe held in a known pose, `reference` (the
  // holder's), make the mount such that the newest sensor orientation maps onto it:
  // mount = sensor⁻¹ × reference, applied from now on (the pose held is updated too). False, and
  // nothing changes, before any orientation has arrived. The host-side counterpart of
  // send_zero(), which asks the probe itself to re-zero.
  bool calibrate_mount(const Eigen::Quaterniond& reference = Eigen::Quaterniond::Identity());
  const Eigen::Quaterniond& mount() const { return settings_.mount; }

  // Host commands, sent with a deadline: zero (tare: the probe's current orientation becomes
  // identity) and the orientation rate. False when the bus did not take the frame.
  bool send_zero(hal::TimestampUs deadline_us);
  bool request_rate(int rate_hz, hal::TimestampUs deadline_us);

 private:
  bool send(const HostCommand& command, hal::TimestampUs deadline_us);
  hal::PoseHealth health(hal::TimestampUs now_us) const;
  // Rewrites status_text_ for a pose of this health.
  void describe(hal::TimestampUs now_us, hal::PoseHealth pose_health);
  // Moves the state machine on at `now_us` given the health of the pose it reports.
  void advance_state(hal::TimestampUs now_us, std::optional<hal::PoseHealth> health);
  void enter(State next);
  int requested_rate_hz() const;

  hal::CanBus& bus_;
  CanProbeSettings settings_;
  ProbeCodec codec_;
  SequenceTracker sequences_;
  Counters counters_;
  std::optional<hal::PoseSample> pose_;  // the newest good orientation, as a sample
  Eigen::Quaterniond sensor_ = Eigen::Quaterniond::Identity();  // its orientation before the mount
  std::optional<ProbeStatus> status_;
  std::optional<ProbeInput> input_;
  bool was_stale_ = false;
  std::string status_text_;  // reserved; rewritten by latest()
  State state_ = State::kReset;
  hal::TimestampUs state_since_us_ = -1;
  hal::TimestampUs last_request_us_ = -1;
  Perf perf_;
  std::uint8_t command_sequence_ = 0;
  std::uint32_t sample_sequence_ = 0;
};

}  // namespace ultrasim::drivers::probe_can
