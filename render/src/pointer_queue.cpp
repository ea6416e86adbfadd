#include "pointer_queue.hpp"

#include <cmath>

namespace ultrasim::render::detail {

PointerState PointerQueue::advance(std::span<const hal::PointerEvent> events) {
  if (head_ == pending_.size()) {
    pending_.clear();
    head_ = 0;
  }
  pending_.insert(pending_.end(), events.begin(), events.end());
  state_.wheel_notches = 0.0f;
  const float seen_x = state_.x_px, seen_y = state_.y_px;  // where ImGui saw the pointer last
  bool moved = false;  // this frame applied moves or wheel turns
  using Kind = hal::PointerEvent::Kind;
  while (head_ < pending_.size()) {
    const hal::PointerEvent& e = pending_[head_];
    // A bad coordinate (a driver's glitch) is dropped, never handed to the UI.
    if (!std::isfinite(e.x_px) || !std::isfinite(e.y_px) || !std::isfinite(e.wheel_notches)) {
      ++head_;
      continue;
    }
    const bool changes_button =
        (e.kind == Kind::kPress && !state_.down) || (e.kind == Kind::kRelease && state_.down);
    if (changes_button) {
      // A press or release gets a frame of its own, after the moves before it: a drag's moves
      // then fall between its press and its release, where ImGui and the orbit can see them.
      if (moved) break;
      // A finger lands where the pointer was not: ImGui must see it there for a frame before
      // the press (a widget that allows overlap, such as a tab, ignores a press on the frame
      // the pointer arrives on it from another widget).
      if (e.kind == Kind::kPress && (e.x_px != seen_x || e.y_px != seen_y)) {
        state_.x_px = e.x_px;
        state_.y_px = e.y_px;
        break;
      }
      state_.down = e.kind == Kind::kPress;
      state_.x_px = e.x_px;
      state_.y_px = e.y_px;
      ++head_;
      break;
    }
    if (e.kind == Kind::kWheel) {
      state_.wheel_notches += e.wheel_notches;
    } else {
      state_.x_px = e.x_px;
      state_.y_px = e.y_px;
    }
    moved = true;
    ++head_;
  }
  return state_;
}

}  // namespace ultrasim::render::detail
