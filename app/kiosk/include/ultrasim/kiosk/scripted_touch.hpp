#pragma once

// A script's touches (UiEvent) as the pointer events a finger would make, on the controls where
// the screen shows them: a scripted session drives the trainer's real controls, not their
// handlers.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "ultrasim/hal/pointer_input.hpp"
#include "ultrasim/kiosk/script.hpp"
#include "ultrasim/render/scene_layout.hpp"
#include "ultrasim/render/trainer_ui.hpp"

namespace ultrasim::kiosk {

class ScriptedTouch {
 public:
  explicit ScriptedTouch(std::span<const UiEvent> events) : events_(events) {}

  // The pointer events for frame `frame` at script time `now_us`: the touches due by then,
  // placed on the screen the last frame drew (`ui`, `layout`, the B-scan's extent in mm). A
  // touch's steps go out one frame apart (a tap presses, then releases the next frame; a drag
  // moves over eight frames). Returns the events, valid until the next call.
  std::span<const hal::PointerEvent> advance(std::int64_t frame, hal::TimestampUs now_us,
                                             const render::TrainerUi& ui,
                                             const render::ScreenLayout& layout,
                                             float image_width_mm, float image_depth_mm);

  std::int64_t delivered() const { return delivered_; }
  // Taps on a control that was not on screen (a script error, or a control that went missing).
  std::int64_t missed() const { return missed_; }
  // Their labels, for the report (at most the first ten).
  const std::vector<std::string>& missed_labels() const { return missed_labels_; }

 private:
  struct Step {
    std::int64_t frame;
    hal::PointerEvent event;
  };
  std::span<const UiEvent> events_;
  std::size_t next_ = 0;
  std::vector<Step> steps_;  // due in later frames
  std::vector<hal::PointerEvent> out_;
  std::int64_t delivered_ = 0;
  std::int64_t missed_ = 0;
  std::vector<std::string> missed_labels_;
};

}  // namespace ultrasim::kiosk
