#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/hal/camera_frame.hpp"
#include "ultrasim/hal/can_bus.hpp"
#include "ultrasim/hal/clock.hpp"
#include "ultrasim/hal/pose_source.hpp"
#include "ultrasim/hal/probe_source_settings.hpp"

namespace ultrasim::kiosk {

// The probe's pose source as [probe] names it, with the drivers beneath it kept alive: the CAN
// bus under a CAN probe, the camera under a camera tracker.
struct ProbeSource {
  std::unique_ptr<hal::CanBus> bus;
  std::unique_ptr<hal::FrameSource> frames;
  std::unique_ptr<hal::PoseSource> pose;  // last: goes first, before what it reads
  // A device that moves in real time (a CAN interface, a camera, the keyboard): the run must
  // follow the monotonic clock. False for the script and for recordings played on `clock`.
  bool real_time = false;
};

// Builds the source. `keyframes`: the script (source scripted). `script_clock`: the clock
// recordings and the script play on (a run's virtual time); `real_clock`: the monotonic clock
// devices stamp their data with. Throws std::invalid_argument / std::runtime_error naming the
// setting, file or device that is missing or bad (a camera that is not plugged in is not an
// error: it is reported by the source and retried).
ProbeSource make_probe_source(const hal::ProbeSourceSettings& settings,
                              std::vector<drivers::sim_probe::Keyframe> keyframes,
                              const hal::Clock& script_clock, const hal::Clock& real_clock);

// The name [probe] source takes for this kind ("can-replay", ...).
const char* probe_source_key(hal::ProbeSourceKind kind);

}  // namespace ultrasim::kiosk
