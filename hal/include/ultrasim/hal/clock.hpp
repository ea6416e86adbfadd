#pragma once

#include <atomic>
#include <cstdint>

namespace ultrasim::hal {

// Microseconds on a monotonic time line; the origin is the clock's own (not wall time).
using TimestampUs = std::int64_t;

// The only source of time for app/ code: inject it, never read the OS clock directly, so that
// tests drive time deterministically with ManualClock.
class Clock {
 public:
  virtual ~Clock() = default;
  // Current monotonic time in microseconds. Thread-safe, never allocates, never goes backwards.
  virtual TimestampUs now_us() const = 0;
};

// A clock that moves only when told to. For tests and for replaying recorded sessions at a fixed
// frame period. Thread-safe.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(TimestampUs start_us = 0) : now_us_(start_us) {}

  TimestampUs now_us() const override { return now_us_.load(std::memory_order_acquire); }

  // Moves time forward by delta_us (negative deltas are ignored: the clock is monotonic).
  void advance_us(TimestampUs delta_us) {
    if (delta_us > 0) now_us_.fetch_add(delta_us, std::memory_order_acq_rel);
  }

 private:
  std::atomic<TimestampUs> now_us_;
};

}  // namespace ultrasim::hal
