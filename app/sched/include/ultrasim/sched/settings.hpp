#pragma once

#include <cstdint>

namespace ultrasim::sched {

struct FrameBudgetSettings {
  std::int64_t budget_us = 16'667;  // one display frame at 60 Hz
};

}  // namespace ultrasim::sched
