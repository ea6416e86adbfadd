#include "ultrasim/drivers/touch/pointer_decoder.hpp"

#include <linux/input-event-codes.h>

#include <algorithm>

namespace ultrasim::drivers::touch {

PointerDecoder::PointerDecoder(int screen_width_px, int screen_height_px, AxisRange x, AxisRange y)
    : width_px_(static_cast<float>(std::max(screen_width_px, 1))),
      height_px_(static_cast<float>(std::max(screen_height_px, 1))),
      x_range_(x),
      y_range_(y),
      x_px_(0.5f * width_px_),
      y_px_(0.5f * height_px_) {}

namespace {
float scale(std::int32_t v, AxisRange r, float extent) {
  if (r.maximum <= r.minimum) return 0.0f;
  const float f = static_cast<float>(v - r.minimum) / static_cast<float>(r.maximum - r.minimum);
  return std::clamp(f, 0.0f, 1.0f) * (extent - 1.0f);
}
}  // namespace

float PointerDecoder::to_screen_x(std::int32_t v) const {
  return scale(v, x_range_, width_px_);
}
float PointerDecoder::to_screen_y(std::int32_t v) const {
  return scale(v, y_range_, height_px_);
}

void PointerDecoder::feed(const RawInputEvent& e, std::vector<hal::PointerEvent>& out) {
  using Kind = hal::PointerEvent::Kind;
  if (e.type == EV_SYN) {
    if (e.code == SYN_DROPPED) {
      dropping_ = true;
      moved_ = false;
      button_change_ = 0;
      wheel_ = 0.0f;
      return;
    }
    if (e.code != SYN_REPORT) return;
    if (dropping_) {
      dropping_ = false;
      return;
    }
    if (moved_) out.push_back({Kind::kMove, x_px_, y_px_, 0.0f});
    if (button_change_ > 0) out.push_back({Kind::kPress, x_px_, y_px_, 0.0f});
    if (button_change_ < 0) out.push_back({Kind::kRelease, x_px_, y_px_, 0.0f});
    if (wheel_ != 0.0f) out.push_back({Kind::kWheel, x_px_, y_px_, wheel_});
    moved_ = false;
    button_change_ = 0;
    wheel_ = 0.0f;
    return;
  }
  if (dropping_) return;
  switch (e.type) {
    case EV_KEY:
      if (e.code == BTN_TOUCH || e.code == BTN_LEFT) {
        if (e.value == 1) button_change_ = 1;
        if (e.value == 0) button_change_ = -1;
      }
      break;
    case EV_ABS:
      if (e.code == ABS_MT_SLOT) {
        slot_ = e.value;
      } else if ((e.code == ABS_X || (e.code == ABS_MT_POSITION_X && slot_ == 0))) {
        x_px_ = to_screen_x(e.value);
        moved_ = true;
      } else if ((e.code == ABS_Y || (e.code == ABS_MT_POSITION_Y && slot_ == 0))) {
        y_px_ = to_screen_y(e.value);
        moved_ = true;
      } else if (e.code == ABS_MT_TRACKING_ID && slot_ == 0) {
        // A multi-touch screen without BTN_TOUCH: the first finger lands (id) or lifts (-1).
        button_change_ = e.value >= 0 ? 1 : -1;
      }
      break;
    case EV_REL:
      if (e.code == REL_X) {
        x_px_ = std::clamp(x_px_ + static_cast<float>(e.value), 0.0f, width_px_ - 1.0f);
        moved_ = true;
      } else if (e.code == REL_Y) {
        y_px_ = std::clamp(y_px_ + static_cast<float>(e.value), 0.0f, height_px_ - 1.0f);
        moved_ = true;
      } else if (e.code == REL_WHEEL) {
        wheel_ += static_cast<float>(e.value);
      }
      break;
    default:
      break;
  }
}

}  // namespace ultrasim::drivers::touch
