#pragma once

#include <cstddef>
#include <vector>

#include "ultrasim/drivers/can_replay/candump_log.hpp"
#include "ultrasim/hal/can_bus.hpp"
#include "ultrasim/hal/clock.hpp"

namespace ultrasim::drivers::can_replay {

// A CanBus that plays a recorded candump log back in real time on `clock`: the first receive()
// is the log's first frame, and each later frame becomes receivable when as much time has passed
// as the log says (divided by `speed`). Received frames carry that replay time as their
// timestamp. Frames sent to it are kept (a log cannot answer), so the host's commands can be
// checked. A first-class driver: the app reads a replay exactly as it reads a live bus.
class ReplayBus final : public hal::CanBus {
 public:
  struct Options {
    double speed = 1.0;  // > 0; 2 plays twice as fast
    bool loop = false;   // start again after the last frame (soak runs on a short log)
  };

  // `clock` must outlive the bus. Throws std::invalid_argument for an empty log, a speed that
  // is not > 0, or timestamps that go backwards (naming the record).
  ReplayBus(std::vector<CandumpRecord> records, const hal::Clock& clock, Options options);
  ReplayBus(std::vector<CandumpRecord> records, const hal::Clock& clock)
      : ReplayBus(std::move(records), clock, Options{}) {}

  bool send(const hal::CanFrame& frame, hal::TimestampUs deadline_us) override;
  bool receive(hal::ReceivedCanFrame& out) override;
  hal::CanBusStats stats() const override { return stats_; }

  // Every frame of the log has been received (never, when looping).
  bool finished() const { return !options_.loop && next_ == records_.size(); }
  const std::vector<hal::CanFrame>& sent_frames() const { return sent_; }

 private:
  std::vector<CandumpRecord> records_;
  const hal::Clock& clock_;
  Options options_;
  std::size_t next_ = 0;
  hal::TimestampUs start_us_ = -1;  // replay time of the log's first frame (this pass)
  hal::CanBusStats stats_;
  std::vector<hal::CanFrame> sent_;
};

}  // namespace ultrasim::drivers::can_replay
