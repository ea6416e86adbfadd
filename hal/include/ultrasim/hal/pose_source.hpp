#pragma once

#include <optional>
#include <string_view>

#include "ultrasim/hal/pose_sample.hpp"

namespace ultrasim::hal {

// A source of probe poses: a CAN probe, a camera tracker, a replayed log or a scripted simulation.
// Consumers cannot tell them apart.
class PoseSource {
 public:
  virtual ~PoseSource() = default;

  // The newest sample at or before now_us, or nothing if the source has produced none yet.
  // Non-blocking; called from the frame thread once per tick.
  virtual std::optional<PoseSample> latest(TimestampUs now_us) = 0;

  // Short human-readable name for logs and the stats overlay ("scripted", "can0", ...).
  virtual std::string_view name() const = 0;

  // What is wrong, in a few words for the screen and the log ("camera: no markers in view",
  // "bus off"); empty while the source is well. Valid until the next latest(); same thread.
  virtual std::string_view status_text() const { return {}; }
};

}  // namespace ultrasim::hal
