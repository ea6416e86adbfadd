#pragma once

// The soak test's scripted session: a trainee's random scanning for a given time (sweeps along
// the case's scan line, presses to random depths, lifts, tilts, holds, freezes, live method
// switches), reproducible from its seed.

#include <cstdint>
#include <span>

#include "ultrasim/config/case_settings.hpp"
#include "ultrasim/kiosk/script.hpp"

namespace ultrasim::kiosk {

// Seconds per case at the start of a soak script spent switching once through every live method
// (each built on first use): memory measured after it is the steady state's.
inline constexpr double kSoakWarmUpS = 6.0;

// One case of the soak's case list: its scan line and image depth.
struct SoakCase {
  config::CaseScan scan;
  double depth_mm = 40.0;
};

// The warm-up's length for this many cases: kSoakWarmUpS each.
double soak_warm_up_s(std::size_t case_count);

// A soak session of `duration_s` (≥ the warm-up) over the cases' scan lines, presses up to 1.5×
// a case's press depth, at its image depth. The warm-up visits every case (the session restarts
// on each) and every live method there, and ends on the first case; then now and then the
// trainee picks another case (lifting the probe first). `cases` must not be empty. The same
// seed gives the same script. Allocates.
Script soak_script(std::span<const SoakCase> cases, double duration_s, std::uint64_t seed);

}  // namespace ultrasim::kiosk
