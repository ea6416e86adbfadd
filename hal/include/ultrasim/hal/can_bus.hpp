#pragma once

#include <array>
#include <cstdint>
#include <span>

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::hal {

// One classic CAN frame, by value (ArduPilot's AP_HAL::CANFrame in spirit): an 11-bit standard
// or 29-bit extended identifier and up to 8 data bytes.
struct CanFrame {
  static constexpr std::uint32_t kMaxStandardId = 0x7FF;
  static constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;

  std::uint32_t id = 0;
  bool extended = false;    // 29-bit identifier
  bool remote = false;      // remote transmission request: asks for data, carries none
  std::uint8_t length = 0;  // data length code, 0..8
  std::array<std::uint8_t, 8> data{};

  std::span<const std::uint8_t> payload() const {
    return std::span(data).first(remote ? 0 : length);
  }
  // The identifier fits its format and the length is 0..8.
  bool well_formed() const {
    return length <= 8 && id <= (extended ? kMaxExtendedId : kMaxStandardId);
  }
  friend bool operator==(const CanFrame&, const CanFrame&) = default;
};

// A frame as received: when the kernel (or a replay log) says it arrived, monotonic µs.
struct ReceivedCanFrame {
  CanFrame frame;
  TimestampUs timestamp_us = 0;
};

// The controller's error state (ISO 11898-1 fault confinement).
enum class CanBusState : std::uint8_t {
  kErrorActive,   // normal
  kErrorPassive,  // error counters ≥ 128: still on the bus, flagging errors passively
  kBusOff,        // error counter ≥ 256: off the bus until recovered
};

// Counters since the bus was opened.
struct CanBusStats {
  std::uint64_t rx_frames = 0;
  std::uint64_t tx_frames = 0;
  std::uint64_t tx_failures = 0;   // send() refused: queue full or past its deadline
  std::uint64_t rx_overflows = 0;  // frames the receive queue dropped (SO_RXQ_OVFL)
  std::uint64_t error_frames = 0;  // error frames reported by the controller
  std::uint64_t bus_off_events = 0;
  CanBusState state = CanBusState::kErrorActive;
};

// A CAN interface: a SocketCAN socket, a replayed log, a test double. Non-blocking; one thread
// (the driver's) calls it.
class CanBus {
 public:
  virtual ~CanBus() = default;

  // Queues a frame for sending if that can happen by `deadline_us` (monotonic); false when it
  // cannot (queue full, bus off, past the deadline), counted in tx_failures. Does not block.
  virtual bool send(const CanFrame& frame, TimestampUs deadline_us) = 0;

  // The next received frame, if one is waiting; false when none. Does not block.
  virtual bool receive(ReceivedCanFrame& out) = 0;

  virtual CanBusStats stats() const = 0;
};

}  // namespace ultrasim::hal
