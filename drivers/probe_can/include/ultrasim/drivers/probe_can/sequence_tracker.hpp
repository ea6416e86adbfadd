#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace ultrasim::drivers::probe_can {

// The protocol's 8-bit sequence counters, one per message identifier: how many frames went
// missing between two that arrived. Pure bookkeeping; the bring-up tool and the probe driver
// count dropouts with it.
class SequenceTracker {
 public:
  // What a frame's sequence says: the frames missed just before it (0: in order; the first
  // frame of an identifier: 0), or that it repeats the last one (a duplicate).
  struct Step {
    int missed = 0;
    bool duplicate = false;
  };
  Step observe(std::uint32_t id, std::uint8_t sequence);

  // Forgets every identifier (after a reset of the probe, say).
  void reset() { last_.clear(); }

 private:
  std::vector<std::pair<std::uint32_t, std::uint8_t>> last_;  // few identifiers: a flat list
};

}  // namespace ultrasim::drivers::probe_can
