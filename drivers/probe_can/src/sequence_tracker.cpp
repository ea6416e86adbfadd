#include "ultrasim/drivers/probe_can/sequence_tracker.hpp"

namespace ultrasim::drivers::probe_can {

SequenceTracker::Step SequenceTracker::observe(std::uint32_t id, std::uint8_t sequence) {
  for (auto& [known, last] : last_) {
    if (known != id) continue;
    // Modulo 256: 255 → 0 is in order, 254 → 1 missed two.
    const int step = static_cast<std::uint8_t>(sequence - last);
    last = sequence;
    if (step == 0) return {0, true};
    return {step - 1, false};
  }
  last_.emplace_back(id, sequence);
  return {};
}

}  // namespace ultrasim::drivers::probe_can
