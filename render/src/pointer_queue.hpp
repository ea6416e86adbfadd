#pragma once

// The pointer's events as ImGui 1.86 wants them: one state per frame. A tap that arrives within
// one frame (press and release together) would otherwise never be seen pressed, so a press or
// release gets a frame of its own, after the frame of the moves before it; a press somewhere
// new waits a frame behind its move, as if the finger hovered before it touched. Internal to
// render/.

#include <cstddef>
#include <span>
#include <vector>

#include "ultrasim/hal/pointer_input.hpp"

namespace ultrasim::render::detail {

struct PointerState {
  float x_px = -1.0f;  // off screen until the first event
  float y_px = -1.0f;
  bool down = false;
  float wheel_notches = 0.0f;  // this frame's
};

class PointerQueue {
 public:
  // Queues `events` and returns the state for this frame: the moves and wheel turns up to the
  // next press or release, or that press or release alone. Allocates only when more events wait
  // than ever before.
  PointerState advance(std::span<const hal::PointerEvent> events);

  std::size_t waiting() const { return pending_.size() - head_; }

 private:
  std::vector<hal::PointerEvent> pending_;
  std::size_t head_ = 0;
  PointerState state_;
};

}  // namespace ultrasim::render::detail
