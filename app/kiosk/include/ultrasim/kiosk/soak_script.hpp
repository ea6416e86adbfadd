#pragma once

// The soak test's scripted session: a trainee's random scanning for a given time (sweeps along
// the case's scan line, presses to random depths, lifts, tilts, holds, freezes, live method
// switches), reproducible from its seed.

#include <cstdint>
#include <optional>
#include <vector>

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/drivers/sim_probe/scripted_probe.hpp"
#include "ultrasim/sim/settings.hpp"

namespace ultrasim::kiosk {

// A change of the scanner's controls at a moment of a script, as a trainee's button press: the
// freeze and depth controls, or (when `method` is set) the live switch of deformation method.
struct ControlEvent {
  hal::TimestampUs time_us = 0;
  bool frozen = false;
  double depth_mm = 0.0;
  std::optional<sim::EngineKind> method;
};

struct Script {
  std::vector<drivers::sim_probe::Keyframe> keyframes;
  std::vector<ControlEvent> controls;
};

// Seconds at the start of a soak script spent switching once through every live method (each
// built on first use): memory measured after it is the steady state's.
inline constexpr double kSoakWarmUpS = 6.0;

// A soak session of `duration_s` (≥ kSoakWarmUpS) over the case's scan line, presses up to 1.5×
// its press depth; image depth `depth_mm` throughout. The same seed gives the same script.
// Allocates.
Script soak_script(const config::CaseScan& scan, double depth_mm, double duration_s,
                   std::uint64_t seed);

}  // namespace ultrasim::kiosk
