#pragma once

#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::posix {

// hal::Clock on CLOCK_MONOTONIC: unaffected by wall-clock changes (NTP, the user), so frame
// budgets and latencies stay meaningful across a kiosk's uptime.
class MonotonicClock final : public hal::Clock {
 public:
  hal::TimestampUs now_us() const override;
};

}  // namespace ultrasim::drivers::posix
