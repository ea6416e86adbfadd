#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <expected>
#include <memory>
#include <span>
#include <string_view>
#include <variant>

#include "ultrasim/drivers/probe_can/dbc.hpp"
#include "ultrasim/hal/can_bus.hpp"

namespace ultrasim::drivers::probe_can {

// The mock probe's CAN protocol as typed messages. The layout lives in one place, probe.dbc,
// embedded at build time (probe_dbc_text()); the codec reads every signal's bits, scale and
// range from it. Each message ends with a sequence byte and a CRC-8 checksum (probe.dbc's
// comment). A pure decoder: no I/O, no clock.

// Orientation of the probe in its mount-calibrated frame (message ProbeOrientation).
struct ProbeOrientation {
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // unit
  std::uint8_t sequence = 0;
};

// Heartbeat (ProbeStatus). Calibration levels 0 (none) .. 3 (full), as IMU fusion chips report.
struct ProbeStatus {
  int firmware_major = 0;
  int firmware_minor = 0;
  int calibration_system = 0;
  int calibration_gyro = 0;
  int calibration_accel = 0;
  int calibration_mag = 0;
  std::uint16_t error_flags = 0;  // bit meanings in probe.dbc (ProbeErrorFlag)
  int orientation_rate_hz = 0;    // the rate in force, a multiple of 4
  std::uint8_t sequence = 0;
};

enum ProbeErrorFlag : std::uint16_t {
  kImuNotResponding = 1u << 0,
  kImuSelfTestFailed = 1u << 1,
  kRateBelowRequest = 1u << 2,
  kSupplyLow = 1u << 3,
  kCanTransmitErrors = 1u << 4,
  kWatchdogReset = 1u << 5,
};

// Buttons and the compression force sensor (ProbeInput).
struct ProbeInput {
  bool freeze = false, save = false, depth_up = false, depth_down = false, gain_up = false,
       gain_down = false;
  double compression_force_n = 0.0;  // 0 .. 655.35 N in 0.01 N steps
  std::uint8_t sequence = 0;
};

// Host to probe (HostCommand).
enum class HostCommandKind : std::uint8_t { kZero = 1, kSetRate = 2, kRequestStatus = 3 };
struct HostCommand {
  HostCommandKind command = HostCommandKind::kRequestStatus;
  int orientation_rate_hz = 0;  // kSetRate: 1 .. 1000
  std::uint8_t sequence = 0;
};

using ProbeMessage = std::variant<ProbeOrientation, ProbeStatus, ProbeInput, HostCommand>;

// Why a frame was not decoded. A bad frame never becomes a pose.
enum class DecodeError : std::uint8_t {
  kUnknownId,          // not one of the protocol's identifiers (another node's traffic)
  kNotAProtocolFrame,  // extended identifier or remote frame
  kWrongLength,        // data length other than the message's 8 bytes
  kBadChecksum,
  kNonUnitQuaternion,  // x² + y² + z² > 1: no unit quaternion has that vector part
  kBadValue,           // a value outside what the protocol allows (e.g. an unknown command)
};
std::string_view describe(DecodeError error);

// CRC-8/SAE-J1850: polynomial 0x1D, initial 0xFF, final XOR 0xFF, no reflection (check value of
// "123456789": 0x4B).
std::uint8_t crc8_sae_j1850(std::span<const std::uint8_t> bytes);

// The protocol's checksum of a frame: the CRC over the identifier's two bytes (least significant
// first) and data bytes 0..6.
std::uint8_t probe_checksum(std::uint32_t id, std::span<const std::uint8_t> data);

// probe.dbc's text, as built in.
std::string_view probe_dbc_text();

class ProbeCodec {
 public:
  // From the built-in probe.dbc. Throws DbcError or std::invalid_argument if the database lacks
  // a message or signal the codec needs (naming it). Allocates.
  ProbeCodec();
  explicit ProbeCodec(DbcDatabase database);

  // Decodes a received frame; never throws.
  std::expected<ProbeMessage, DecodeError> decode(const hal::CanFrame& frame) const;

  // Encodes a message with its sequence and checksum. Values outside a signal's range are
  // clamped to it (an orientation is normalised and its scalar part made non-negative).
  hal::CanFrame encode(const ProbeMessage& message) const;

  const DbcDatabase& database() const { return db_; }
  static constexpr std::uint32_t kStatusId = 0x100;
  static constexpr std::uint32_t kOrientationId = 0x101;
  static constexpr std::uint32_t kInputId = 0x102;
  static constexpr std::uint32_t kHostCommandId = 0x200;

 private:
  struct Layout;  // copies of the signals each message needs, resolved once; immutable
  DbcDatabase db_;
  std::shared_ptr<const Layout> layout_;
};

}  // namespace ultrasim::drivers::probe_can
