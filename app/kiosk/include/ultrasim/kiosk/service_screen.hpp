#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "ultrasim/hal/pointer_input.hpp"
#include "ultrasim/hal/pose_source.hpp"
#include "ultrasim/kiosk/session.hpp"
#include "ultrasim/render/trainer_ui.hpp"
#include "ultrasim/sched/scheduler.hpp"

namespace ultrasim::kiosk {

// The service screen's lines: what a bring-up engineer checks first. Rebuilt a few times a
// second (it allocates), not every frame.
struct ServiceScreen {
  std::vector<std::string> values;
  std::vector<render::ServiceLine> lines;
  // Reads them again: the display's name, the probe source and what it says, the touch device
  // (null: none), the session, the scheduler's frame stats, the process's memory (unset: "-").
  void refresh(std::string_view display, hal::PoseSource& probe, std::string_view probe_status,
               const hal::PointerSource* pointer, const Session& session,
               std::string_view case_name, const sched::Scheduler& scheduler,
               const std::function<std::int64_t()>& resident_memory_kib);
};

}  // namespace ultrasim::kiosk
