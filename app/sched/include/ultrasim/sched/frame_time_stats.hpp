#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace ultrasim::sched {

// Accounting for one timed quantity (a whole frame, or one stage of it): count, min/mean/max,
// percentiles from a fixed-resolution histogram, and how often it exceeded its budget.
// Sized once at construction; record() never allocates, so hours-long soak runs cost nothing
// per frame. Not thread-safe: one recording thread.
class FrameTimeStats {
 public:
  // budget_us: a sample above this counts as a deadline miss (0: no budget).
  // resolution_us × bin_count is the histogram range; samples beyond it land in the last bin
  // (percentiles there read as the exact maximum).
  explicit FrameTimeStats(std::int64_t budget_us = 0, std::int64_t resolution_us = 10,
                          int bin_count = 20'000);

  void record(std::int64_t duration_us);

  std::int64_t count() const { return count_; }
  std::int64_t deadline_misses() const { return misses_; }
  std::int64_t budget_us() const { return budget_us_; }
  std::int64_t min_us() const { return count_ ? min_ : 0; }
  std::int64_t max_us() const { return count_ ? max_ : 0; }
  double mean_us() const { return count_ ? static_cast<double>(sum_) / count_ : 0.0; }
  // Nearest-rank percentile, p in [0, 100], to the histogram's resolution (upper bin edge,
  // never above the true maximum). 0 when nothing was recorded.
  std::int64_t percentile_us(double p) const;

 private:
  std::int64_t budget_us_;
  std::int64_t resolution_us_;
  std::vector<std::int64_t> bins_;
  std::int64_t count_ = 0, misses_ = 0, sum_ = 0;
  std::int64_t min_ = std::numeric_limits<std::int64_t>::max(), max_ = 0;
};

}  // namespace ultrasim::sched
