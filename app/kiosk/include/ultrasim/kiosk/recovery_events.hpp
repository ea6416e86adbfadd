#pragma once

// The run report's log of what the deformation methods recovered from: each run of consecutive
// frames with the same recovery (a frame re-run with smaller steps, a press refused and the last
// good shape kept, a reset to rest) on one case and method, with when it started and how hard
// the probe pressed during it. A soak's counts say how often; this says when and under what.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::kiosk {

struct RecoveryEvent {
  sim::Recovery kind = sim::Recovery::kNone;
  sim::DivergenceCause cause = sim::DivergenceCause::kNone;  // what the method's checks found
  std::int64_t first_frame = 0;
  std::int64_t frames = 0;
  double time_s = 0.0;  // the first frame's time on the run's clock
  std::string case_name;
  std::string method;  // engine_key
  double max_contact_force_n = 0.0;
};

class RecoveryEvents {
 public:
  // Past this many events the rest are only counted: an hours-long soak refusing presses now and
  // then must not grow its report (or its memory) without bound.
  static constexpr std::size_t kMaxEvents = 256;

  // One frame's outcome. Frames without a recovery end the current event; a frame continuing the
  // last event (the next frame, the same kind, cause, case and method) extends it.
  void record(std::int64_t frame, double time_s, std::string_view case_name,
              std::string_view method, sim::Recovery recovery, double contact_force_n,
              sim::DivergenceCause cause = sim::DivergenceCause::kNone);

  const std::vector<RecoveryEvent>& events() const { return events_; }
  std::int64_t dropped() const { return dropped_; }  // events past kMaxEvents

 private:
  std::vector<RecoveryEvent> events_;
  std::int64_t dropped_ = 0;
  // The last frame with a recovery and what it was, kept past kMaxEvents to count events.
  std::int64_t last_frame_ = -2;
  sim::Recovery last_kind_ = sim::Recovery::kNone;
  sim::DivergenceCause last_cause_ = sim::DivergenceCause::kNone;
  std::string last_case_, last_method_;
};

}  // namespace ultrasim::kiosk
