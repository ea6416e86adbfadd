#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "ultrasim/hal/can_bus.hpp"
#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::socketcan {

// What an error frame (CAN_ERR_FLAG set in `can_id`, classes in linux/can/error.h) says about the
// bus, into `stats`: counted, and bus off / error passive / back to error active. Pure; public for
// tests (no host kernel here can make error frames).
void apply_error_frame(hal::CanBusStats& stats, std::uint32_t can_id,
                       std::span<const std::uint8_t, 8> data);

// A Linux SocketCAN interface (can0, vcan0, ...) as a hal::CanBus: a non-blocking raw socket
// with the kernel's receive timestamps (SO_TIMESTAMP, mapped onto `clock`), the receive queue's
// drop count (SO_RXQ_OVFL: the kernel sends it with each frame queued after the drops, so
// rx_overflows catches up when the next frame is received) and every class of error frame
// (CAN_RAW_ERR_FILTER) turned into bus stats and state. Error frames are accounted, never
// returned as data. Not yet: bus-off recovery by restarting the controller (netlink), which
// needs a real CAN controller to test.
class SocketCanBus final : public hal::CanBus {
 public:
  // Opens and binds the interface. Throws std::runtime_error naming the interface and the
  // system's reason when it cannot (no such interface, no AF_CAN in this kernel, ...).
  // `clock` (monotonic, µs) must outlive the bus.
  SocketCanBus(const std::string& interface, const hal::Clock& clock);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  bool send(const hal::CanFrame& frame, hal::TimestampUs deadline_us) override;
  bool receive(hal::ReceivedCanFrame& out) override;
  hal::CanBusStats stats() const override { return stats_; }

  const std::string& interface() const { return interface_; }

 private:
  std::string interface_;
  const hal::Clock& clock_;
  int fd_ = -1;
  hal::CanBusStats stats_;
};

}  // namespace ultrasim::drivers::socketcan
