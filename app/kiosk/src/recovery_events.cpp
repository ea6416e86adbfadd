#include "ultrasim/kiosk/recovery_events.hpp"

#include <algorithm>
#include <cmath>

namespace ultrasim::kiosk {

void RecoveryEvents::record(std::int64_t frame, double time_s, std::string_view case_name,
                            std::string_view method, sim::Recovery recovery, double contact_force_n,
                            sim::DivergenceCause cause) {
  if (recovery == sim::Recovery::kNone) return;
  // A frame that blew up may report no finite force; the report is JSON, which has no NaN.
  if (!std::isfinite(contact_force_n)) contact_force_n = 0.0;
  const bool continues = frame == last_frame_ + 1 && recovery == last_kind_ &&
                         cause == last_cause_ && case_name == last_case_ && method == last_method_;
  last_frame_ = frame;
  if (continues) {
    // Past the cap the continued event is a dropped one: nothing to extend.
    if (dropped_ == 0) {
      RecoveryEvent& e = events_.back();
      e.frames += 1;
      e.max_contact_force_n = std::max(e.max_contact_force_n, contact_force_n);
    }
    return;
  }
  last_kind_ = recovery;
  last_cause_ = cause;
  last_case_.assign(case_name);
  last_method_.assign(method);
  if (events_.size() == kMaxEvents) {
    ++dropped_;
    return;
  }
  events_.push_back({recovery, cause, frame, 1, time_s, std::string(case_name), std::string(method),
                     contact_force_n});
}

}  // namespace ultrasim::kiosk
