#include "ultrasim/drivers/can_replay/replay_bus.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace ultrasim::drivers::can_replay {

ReplayBus::ReplayBus(std::vector<CandumpRecord> records, const hal::Clock& clock, Options options)
    : records_(std::move(records)), clock_(clock), options_(options) {
  if (records_.empty()) throw std::invalid_argument("ReplayBus: the log holds no frame");
  if (!(options_.speed > 0.0) || !std::isfinite(options_.speed)) {
    throw std::invalid_argument("ReplayBus: speed must be > 0");
  }
  for (std::size_t i = 1; i < records_.size(); ++i) {
    if (records_[i].timestamp_us < records_[i - 1].timestamp_us) {
      throw std::invalid_argument("ReplayBus: record " + std::to_string(i + 1) +
                                  "'s timestamp is earlier than the one before it");
    }
  }
  if (options_.loop && records_.back().timestamp_us == records_.front().timestamp_us) {
    // A pass would take no time: every receive() would start another.
    throw std::invalid_argument("ReplayBus: a log that spans no time cannot loop");
  }
}

bool ReplayBus::send(const hal::CanFrame& frame, hal::TimestampUs deadline_us) {
  if (!frame.well_formed() || clock_.now_us() > deadline_us) {
    ++stats_.tx_failures;
    return false;
  }
  sent_.push_back(frame);
  ++stats_.tx_frames;
  return true;
}

bool ReplayBus::receive(hal::ReceivedCanFrame& out) {
  const hal::TimestampUs now = clock_.now_us();
  if (next_ == records_.size()) {
    if (!options_.loop) return false;
    // The next pass starts one mean frame interval after the last frame; a reader that fell more
    // than a pass behind starts it now rather than replay the passes it missed at once.
    const auto span_us = records_.back().timestamp_us - records_.front().timestamp_us;
    const auto interval_us = span_us / static_cast<std::int64_t>(records_.size() - 1);
    const auto pass_us =
        static_cast<hal::TimestampUs>(static_cast<double>(span_us + interval_us) / options_.speed);
    start_us_ = std::max(start_us_ + pass_us, now - pass_us);
    next_ = 0;
  }
  if (start_us_ < 0) start_us_ = now;
  const auto offset_us = records_[next_].timestamp_us - records_.front().timestamp_us;
  const hal::TimestampUs due_us =
      start_us_ + static_cast<hal::TimestampUs>(static_cast<double>(offset_us) / options_.speed);
  if (due_us > now) return false;
  out.frame = records_[next_].frame;
  out.timestamp_us = due_us;
  ++next_;
  ++stats_.rx_frames;
  return true;
}

}  // namespace ultrasim::drivers::can_replay
