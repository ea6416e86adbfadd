#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ultrasim::tools {

// The host → probe → host round trip the bring-up tool measures: the time from sending a status
// request to the status that answers it arriving (its kernel receive timestamp), µs.
class RoundTripMeter {
 public:
  // A request sent at sent_us (the bus's clock).
  void sent(std::int64_t sent_us) {
    if (pending_us_ >= 0) ++lost_;  // the last one was never answered
    pending_us_ = sent_us;
  }
  // A status frame received at received_us: the answer to the pending request, if any.
  void status_received(std::int64_t received_us) {
    if (pending_us_ < 0 || received_us < pending_us_) return;
    round_trips_us_.push_back(received_us - pending_us_);
    pending_us_ = -1;
  }
  bool waiting() const { return pending_us_ >= 0; }
  // Gives up on the pending request (counted as lost).
  void give_up() {
    if (pending_us_ >= 0) ++lost_;
    pending_us_ = -1;
  }

  const std::vector<std::int64_t>& round_trips_us() const { return round_trips_us_; }
  std::int64_t lost() const { return lost_; }

  // {"count": n, "lost": n, "p50_us": .., "p99_us": .., "max_us": ..} (nearest rank).
  std::string json() const;

 private:
  std::int64_t pending_us_ = -1;
  std::int64_t lost_ = 0;
  std::vector<std::int64_t> round_trips_us_;
};

}  // namespace ultrasim::tools
