#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace ultrasim::hal {

// One step of the trainer's pointer, a finger on the touch screen or the mouse, in screen
// pixels (origin top left, y down). A touch is a press where the finger lands, moves while it
// slides and a release where it lifts; a mouse's moves come with or without its button held.
struct PointerEvent {
  enum class Kind : std::uint8_t { kMove, kPress, kRelease, kWheel };
  Kind kind = Kind::kMove;
  float x_px = 0.0f;
  float y_px = 0.0f;
  float wheel_notches = 0.0f;  // kWheel: + away from the user (zoom in), - towards
};

// Where the trainer's pointer events come from: a touch screen or mouse (drivers/evdev), or a
// test's script. Non-blocking; the frame thread takes what arrived each frame.
class PointerSource {
 public:
  virtual ~PointerSource() = default;

  // The events since the last call, oldest first; valid until the next call. Never blocks.
  virtual std::span<const PointerEvent> poll() = 0;

  // Short name for logs and the service screen ("/dev/input/event3").
  virtual std::string_view name() const = 0;

  // What is wrong ("touch screen unplugged"); empty while well. Valid until the next poll().
  virtual std::string_view status_text() const { return {}; }
};

}  // namespace ultrasim::hal
