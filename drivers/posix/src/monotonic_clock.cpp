#include "ultrasim/drivers/posix/monotonic_clock.hpp"

#include <time.h>

namespace ultrasim::drivers::posix {

hal::TimestampUs MonotonicClock::now_us() const {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<hal::TimestampUs>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1'000;
}

}  // namespace ultrasim::drivers::posix
