#include "ultrasim/tools/round_trip_meter.hpp"

#include <algorithm>
#include <cmath>

namespace ultrasim::tools {

std::string RoundTripMeter::json() const {
  std::vector<std::int64_t> sorted = round_trips_us_;
  std::sort(sorted.begin(), sorted.end());
  const auto rank = [&sorted](double q) -> std::int64_t {
    if (sorted.empty()) return 0;
    const auto i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size())));
    return sorted[std::clamp<std::size_t>(i, 1, sorted.size()) - 1];
  };
  return "{\"count\": " + std::to_string(sorted.size()) + ", \"lost\": " + std::to_string(lost_) +
         ", \"p50_us\": " + std::to_string(rank(0.5)) +
         ", \"p99_us\": " + std::to_string(rank(0.99)) +
         ", \"max_us\": " + std::to_string(rank(1.0)) + "}";
}

}  // namespace ultrasim::tools
