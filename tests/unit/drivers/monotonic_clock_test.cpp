#include "ultrasim/drivers/posix/monotonic_clock.hpp"

#include <gtest/gtest.h>

#include <thread>

namespace ultrasim::drivers::posix {
namespace {

TEST(MonotonicClock, NeverGoesBackwardsAndAdvancesWithTime) {
  const MonotonicClock clock;
  hal::TimestampUs last = clock.now_us();
  for (int i = 0; i < 1000; ++i) {
    const hal::TimestampUs now = clock.now_us();
    ASSERT_GE(now, last);
    last = now;
  }
  const hal::TimestampUs before = clock.now_us();
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_GE(clock.now_us() - before, 5'000);
}

TEST(ManualClock, MovesOnlyForwardWhenTold) {
  hal::ManualClock clock(100);
  EXPECT_EQ(clock.now_us(), 100);
  clock.advance_us(16'667);
  EXPECT_EQ(clock.now_us(), 16'767);
  clock.advance_us(-50);
  EXPECT_EQ(clock.now_us(), 16'767);
}

}  // namespace
}  // namespace ultrasim::drivers::posix
