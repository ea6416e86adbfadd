#include <linux/input-event-codes.h>

#include <algorithm>

#include "ultrasim/drivers/keyboard/keyboard_probe.hpp"

namespace ultrasim::drivers::keyboard {

namespace {

constexpr double kPi = 3.14159265358979323846;

}  // namespace

KeyboardProbeModel::KeyboardProbeModel(const KeyboardProbeSettings& settings)
    : settings_(settings), position_mm_(settings.start_mm) {}

void KeyboardProbeModel::apply(const InputEvent& event) {
  if (event.kind == InputEvent::Kind::kKey) {
    if (event.code == KEY_R && event.value == 1) {
      position_mm_ = settings_.start_mm;
      orientation_ = Eigen::Quaterniond::Identity();
    }
    if (event.code < held_.size()) held_[event.code] = event.value != 0;
    return;
  }
  switch (event.code) {
    case REL_X:
      position_mm_.x() += settings_.mouse_mm_per_count * event.value;
      break;
    case REL_Y:
      position_mm_.y() += settings_.mouse_mm_per_count * event.value;
      break;
    case REL_WHEEL:  // away from the user (positive) lifts
      position_mm_.z() -= settings_.wheel_mm_per_notch * event.value;
      break;
    default:
      break;
  }
}

void KeyboardProbeModel::advance(hal::TimestampUs now_us) {
  if (last_us_ < 0 || now_us <= last_us_) {
    last_us_ = std::max(last_us_, now_us);
    return;
  }
  const double dt_s = static_cast<double>(now_us - last_us_) * 1e-6;
  last_us_ = now_us;
  const auto axis = [this](int minus, int plus) {
    return static_cast<double>(held_[static_cast<std::size_t>(plus)]) -
           static_cast<double>(held_[static_cast<std::size_t>(minus)]);
  };
  const Eigen::Vector3d velocity(axis(KEY_LEFT, KEY_RIGHT), axis(KEY_UP, KEY_DOWN),
                                 axis(KEY_PAGEUP, KEY_PAGEDOWN));
  position_mm_ += settings_.speed_mm_per_s * dt_s * velocity;
  const double turn = settings_.turn_deg_per_s * kPi / 180.0 * dt_s;
  const Eigen::Vector3d spin(axis(KEY_S, KEY_W), axis(KEY_A, KEY_D), axis(KEY_Q, KEY_E));
  if (spin.squaredNorm() > 0.0) {
    // About the probe's own axes: rocking and tilting as a hand does.
    orientation_ = (orientation_ *
                    Eigen::Quaterniond(Eigen::AngleAxisd(turn * spin.norm(), spin.normalized())))
                       .normalized();
  }
}

void TerminalKeyDecoder::feed(const std::uint8_t* bytes, std::size_t count,
                              std::vector<InputEvent>& out) {
  const auto press = [&out](std::uint16_t code) {
    out.push_back({InputEvent::Kind::kKey, code, 1});
  };
  for (std::size_t i = 0; i < count; ++i) {
    pending_.push_back(static_cast<char>(bytes[i]));
    if (pending_[0] != '\x1b') {
      switch (pending_[0]) {
        case 'w':
        case 'W':
          press(KEY_W);
          break;
        case 's':
        case 'S':
          press(KEY_S);
          break;
        case 'a':
        case 'A':
          press(KEY_A);
          break;
        case 'd':
        case 'D':
          press(KEY_D);
          break;
        case 'q':
        case 'Q':
          press(KEY_Q);
          break;
        case 'e':
        case 'E':
          press(KEY_E);
          break;
        case 'r':
        case 'R':
          press(KEY_R);
          break;
        default:
          break;
      }
      pending_.clear();
      continue;
    }
    // ESC [ A..D (arrows), ESC [ 5 ~ / ESC [ 6 ~ (page up/down); anything else is dropped.
    if (pending_.size() == 1) continue;
    if (pending_[1] != '[') {
      pending_.clear();
      continue;
    }
    if (pending_.size() == 2) continue;
    const char c = pending_[2];
    if (c == 'A') press(KEY_UP);
    if (c == 'B') press(KEY_DOWN);
    if (c == 'C') press(KEY_RIGHT);
    if (c == 'D') press(KEY_LEFT);
    if ((c == '5' || c == '6') && pending_.size() == 3) continue;
    if ((c == '5' || c == '6') && pending_[3] == '~') press(c == '5' ? KEY_PAGEUP : KEY_PAGEDOWN);
    pending_.clear();
  }
}

}  // namespace ultrasim::drivers::keyboard
