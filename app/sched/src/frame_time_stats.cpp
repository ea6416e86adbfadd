#include "ultrasim/sched/frame_time_stats.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ultrasim::sched {

FrameTimeStats::FrameTimeStats(std::int64_t budget_us, std::int64_t resolution_us, int bin_count)
    : budget_us_(budget_us), resolution_us_(resolution_us) {
  if (resolution_us < 1 || bin_count < 1) {
    throw std::invalid_argument("FrameTimeStats: resolution and bin count must be >= 1");
  }
  bins_.assign(static_cast<std::size_t>(bin_count), 0);
}

void FrameTimeStats::record(std::int64_t duration_us) {
  duration_us = std::max<std::int64_t>(duration_us, 0);
  const auto bin = std::min<std::int64_t>(duration_us / resolution_us_,
                                          static_cast<std::int64_t>(bins_.size()) - 1);
  ++bins_[static_cast<std::size_t>(bin)];
  ++count_;
  sum_ += duration_us;
  min_ = std::min(min_, duration_us);
  max_ = std::max(max_, duration_us);
  if (budget_us_ > 0 && duration_us > budget_us_) ++misses_;
}

std::int64_t FrameTimeStats::percentile_us(double p) const {
  if (count_ == 0) return 0;
  const double clamped = std::clamp(p, 0.0, 100.0);
  const auto rank = std::max<std::int64_t>(
      1, static_cast<std::int64_t>(std::ceil(clamped / 100.0 * static_cast<double>(count_))));
  std::int64_t seen = 0;
  for (std::size_t b = 0; b < bins_.size(); ++b) {
    seen += bins_[b];
    if (seen >= rank) {
      if (b + 1 == bins_.size()) return max_;  // the overflow bin has no upper edge
      const std::int64_t upper_edge = static_cast<std::int64_t>(b + 1) * resolution_us_;
      return std::clamp(upper_edge, min_, max_);
    }
  }
  return max_;
}

}  // namespace ultrasim::sched
