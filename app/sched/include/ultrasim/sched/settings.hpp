#pragma once

#include <cstdint>

namespace ultrasim::sched {

// The kiosk's frame: its budget and its tasks' (Scheduler, TaskSpec::budget_us). The defaults
// are what each stage takes on the default case on a 2-core machine with software rendering
// (docs/benchmarks.md), with some room: all four fit in one 60 Hz frame.
struct FrameBudgetSettings {
  std::int64_t budget_us = 16'667;            // one display frame at 60 Hz
  std::int64_t simulation_budget_us = 4'000;  // contact and deformation; runs every frame
  std::int64_t bscan_budget_us = 3'000;       // skipped (the image held) when it does not fit
  std::int64_t view_budget_us = 500;          // mesh and vessel surfaces for the 3D view; likewise
  std::int64_t render_budget_us = 9'000;      // drawing and hand-off; runs every frame
};

}  // namespace ultrasim::sched
