#pragma once

// The median of a benchmark's repetitions (the summaries the benchmarks print as ratios).

#include <algorithm>
#include <vector>

namespace ultrasim::bench {

// The middle value (the mean of the two middle ones for an even count); 0 for none.
inline double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::ranges::sort(values);
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

}  // namespace ultrasim::bench
