#include "ultrasim/kiosk/scripted_touch.hpp"

#include <algorithm>

namespace ultrasim::kiosk {

std::span<const hal::PointerEvent> ScriptedTouch::advance(
    std::int64_t frame, hal::TimestampUs now_us, const render::TrainerUi& ui,
    const render::ScreenLayout& layout, float image_width_mm, float image_depth_mm) {
  using Kind = hal::PointerEvent::Kind;
  const auto queue = [&](std::int64_t in_frames, Kind kind, float x, float y, float wheel = 0) {
    steps_.push_back({frame + in_frames, {kind, x, y, wheel}});
  };
  while (next_ < events_.size() && events_[next_].time_us <= now_us) {
    const UiEvent& e = events_[next_++];
    ++delivered_;
    switch (e.kind) {
      case UiEvent::Kind::kTap: {
        const auto rect = ui.widget_rect(e.widget);
        if (!rect) {
          ++missed_;
          if (missed_labels_.size() < 10) missed_labels_.push_back(e.widget);
          break;
        }
        const auto x = static_cast<float>(rect->center_x_px());
        const auto y = static_cast<float>(rect->center_y_px());
        queue(0, Kind::kMove, x, y);
        queue(0, Kind::kPress, x, y);
        queue(1, Kind::kRelease, x, y);
        break;
      }
      case UiEvent::Kind::kTapImage: {
        const render::PixelRect& image = layout.bscan_image;
        const float x = static_cast<float>(image.x_px) +
                        e.image_mm[0] / image_width_mm * static_cast<float>(image.width_px);
        const float y = static_cast<float>(image.y_px) +
                        e.image_mm[1] / image_depth_mm * static_cast<float>(image.height_px);
        queue(0, Kind::kMove, x, y);
        queue(0, Kind::kPress, x, y);
        queue(1, Kind::kRelease, x, y);
        break;
      }
      case UiEvent::Kind::kDragView: {
        const auto x = static_cast<float>(layout.view_3d.center_x_px());
        const auto y = static_cast<float>(layout.view_3d.center_y_px());
        queue(0, Kind::kMove, x, y);
        queue(0, Kind::kPress, x, y);
        constexpr int kSteps = 8;
        for (int i = 1; i <= kSteps; ++i) {
          const float f = static_cast<float>(i) / kSteps;
          queue(i, Kind::kMove, x + f * e.drag_px[0], y + f * e.drag_px[1]);
        }
        queue(kSteps + 1, Kind::kRelease, x + e.drag_px[0], y + e.drag_px[1]);
        break;
      }
      case UiEvent::Kind::kWheelView: {
        const auto x = static_cast<float>(layout.view_3d.center_x_px());
        const auto y = static_cast<float>(layout.view_3d.center_y_px());
        queue(0, Kind::kMove, x, y);
        queue(0, Kind::kWheel, x, y, e.wheel_notches);
        break;
      }
    }
  }
  out_.clear();
  for (const Step& s : steps_) {
    if (s.frame <= frame) out_.push_back(s.event);
  }
  std::erase_if(steps_, [&](const Step& s) { return s.frame <= frame; });
  return out_;
}

}  // namespace ultrasim::kiosk
