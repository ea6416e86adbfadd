#pragma once

#include <cstdint>
#include <vector>

#include "ultrasim/hal/pointer_input.hpp"

namespace ultrasim::drivers::touch {

// One evdev record (struct input_event without its time): linux/input-event-codes.h numbering.
struct RawInputEvent {
  std::uint16_t type = 0;
  std::uint16_t code = 0;
  std::int32_t value = 0;
};

// An absolute axis's range as the device reports it (EVIOCGABS).
struct AxisRange {
  std::int32_t minimum = 0;
  std::int32_t maximum = 0;  // <= minimum: the axis is absent
};

// The pure part: evdev records from a touch screen (single-touch ABS_X/ABS_Y with BTN_TOUCH, or
// the first multi-touch slot's ABS_MT_POSITION_X/Y and tracking id) or a mouse (REL_X/REL_Y
// moving a cursor kept on the screen, BTN_LEFT, REL_WHEEL) into pointer events in screen pixels.
// Each SYN_REPORT closes a frame of the device: its position first, then a press or release;
// a SYN_DROPPED discards the records up to the next report (the kernel lost some). Touches on
// other multi-touch slots than the first are ignored: the controls take one finger.
class PointerDecoder {
 public:
  // The screen the pointer addresses; the touch axes' ranges (absent for a mouse). The mouse's
  // cursor starts at the screen's centre.
  PointerDecoder(int screen_width_px, int screen_height_px, AxisRange x = {}, AxisRange y = {});

  // Appends what `e` completes to `out`. No allocation beyond `out`'s growth.
  void feed(const RawInputEvent& e, std::vector<hal::PointerEvent>& out);

 private:
  float to_screen_x(std::int32_t v) const;
  float to_screen_y(std::int32_t v) const;

  float width_px_, height_px_;
  AxisRange x_range_, y_range_;
  float x_px_, y_px_;      // where the pointer is
  bool moved_ = false;     // since the last report
  int button_change_ = 0;  // +1 pressed, -1 released since the last report
  float wheel_ = 0.0f;     // notches since the last report
  int slot_ = 0;           // the multi-touch slot the records address
  bool dropping_ = false;  // after SYN_DROPPED, until SYN_REPORT
};

}  // namespace ultrasim::drivers::touch
