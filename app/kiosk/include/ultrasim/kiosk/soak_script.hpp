#pragma once

// The soak test's scripted session: a trainee's random scanning for a given time (sweeps along
// the case's scan line, presses to random depths, lifts, tilts, holds, freezes, live method
// switches), reproducible from its seed.

#include <cstdint>

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/kiosk/script.hpp"

namespace ultrasim::kiosk {

// Seconds at the start of a soak script spent switching once through every live method (each
// built on first use): memory measured after it is the steady state's.
inline constexpr double kSoakWarmUpS = 6.0;

// A soak session of `duration_s` (≥ kSoakWarmUpS) over the case's scan line, presses up to 1.5×
// its press depth; image depth `depth_mm` throughout. The same seed gives the same script.
// Allocates.
Script soak_script(const config::CaseScan& scan, double depth_mm, double duration_s,
                   std::uint64_t seed);

}  // namespace ultrasim::kiosk
