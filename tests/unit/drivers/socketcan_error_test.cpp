// Error frames into bus state (the VM test cannot make a virtual CAN interface produce them):
// classes as linux/can/error.h defines them.

#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>

#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"

namespace ultrasim::drivers::socketcan {
namespace {

TEST(SocketCanErrorFrames, BusOffPassiveAndRecoveryChangeTheState) {
  hal::CanBusStats stats;
  std::array<std::uint8_t, 8> data{};
  data[1] = CAN_ERR_CRTL_RX_PASSIVE;
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_CRTL, data);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorPassive);
  data[1] = 0;
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_BUSOFF, data);
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_BUSOFF, data);  // still off: one event
  EXPECT_EQ(stats.state, hal::CanBusState::kBusOff);
  EXPECT_EQ(stats.bus_off_events, 1u);
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_RESTARTED, data);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorActive);
  data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_CRTL, data);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorPassive);
  data[1] = CAN_ERR_CRTL_TX_WARNING;  // from passive down to the warning level: active again
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_CRTL, data);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorActive);
  data[1] = CAN_ERR_CRTL_RX_PASSIVE;
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_CRTL, data);
  data[1] = CAN_ERR_CRTL_ACTIVE;
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_CRTL, data);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorActive);
  apply_error_frame(stats, CAN_ERR_FLAG | CAN_ERR_PROT, data);  // counted, no state change
  EXPECT_EQ(stats.error_frames, 9u);
  EXPECT_EQ(stats.state, hal::CanBusState::kErrorActive);
}

}  // namespace
}  // namespace ultrasim::drivers::socketcan
