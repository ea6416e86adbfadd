#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ultrasim/hal/pose_source.hpp"

namespace ultrasim::drivers::keyboard {

struct KeyboardProbeSettings {
  Eigen::Vector3d start_mm{0.0, 0.0, -5.0};  // patient space; R puts the probe back here
  double speed_mm_per_s = 40.0;              // a held arrow or page key
  double turn_deg_per_s = 45.0;              // a held W/S, A/D or Q/E key
  double mouse_mm_per_count = 0.1;           // relative mouse motion moves the probe
  double wheel_mm_per_notch = 0.5;           // the wheel presses (down) or lifts (up)
};

// One input event, as Linux's evdev reports it (linux/input-event-codes.h numbering).
struct InputEvent {
  enum class Kind : std::uint8_t { kKey, kRelative };
  Kind kind = Kind::kKey;
  std::uint16_t code = 0;  // KEY_* for keys, REL_* for relative axes
  std::int32_t value = 0;  // keys: 1 pressed, 0 released, 2 auto-repeat; axes: the motion
};

// The pure part: keys and mouse moving a probe. Held keys move it at a steady rate, so the
// motion depends on time, not on the keyboard's repeat rate:
//   arrows: along patient x (left/right) and y (up/down); Page Up/Down: lift / press (z);
//   W/S: rock about the probe's x; A/D: tilt about its y; Q/E: turn about its beam; R: reset.
//   Mouse: x/y motion moves it, the wheel presses and lifts.
class KeyboardProbeModel {
 public:
  explicit KeyboardProbeModel(const KeyboardProbeSettings& settings);

  void apply(const InputEvent& event);
  // Moves the probe by the keys held since the last advance. No allocation.
  void advance(hal::TimestampUs now_us);
  // Releases every key (the terminal reports presses only; a pause means the key is up).
  void release_all() { held_.fill(false); }

  const Eigen::Vector3d& position_mm() const { return position_mm_; }
  const Eigen::Quaterniond& orientation() const { return orientation_; }

 private:
  KeyboardProbeSettings settings_;
  Eigen::Vector3d position_mm_;
  Eigen::Quaterniond orientation_ = Eigen::Quaterniond::Identity();
  std::array<bool, 256> held_{};
  hal::TimestampUs last_us_ = -1;
};

// Turns a terminal's bytes (raw mode) into key presses: letters, and the escape sequences of
// the arrow and page keys. Bytes may arrive split anywhere. Each key comes out as a press.
class TerminalKeyDecoder {
 public:
  // Appends the presses the bytes complete to `out`.
  void feed(const std::uint8_t* bytes, std::size_t count, std::vector<InputEvent>& out);

 private:
  std::string pending_;
};

// The keyboard probe as a hal::PoseSource over a file descriptor it reads without blocking: an
// evdev node (struct input_event records) or a terminal (bytes; a key counts as held until
// 150 ms pass without its repeat). A device that goes away (unplugged) makes the pose a fault
// with the last pose kept and the device named in status_text().
class KeyboardProbe final : public hal::PoseSource {
 public:
  enum class Transport : std::uint8_t { kEvdev, kTerminal };
  // Takes ownership of `fd` (closed on destruction; a terminal's mode is restored).
  KeyboardProbe(int fd, Transport transport, std::string name,
                const KeyboardProbeSettings& settings);
  ~KeyboardProbe() override;
  KeyboardProbe(const KeyboardProbe&) = delete;
  KeyboardProbe& operator=(const KeyboardProbe&) = delete;

  std::optional<hal::PoseSample> latest(hal::TimestampUs now_us) override;
  std::string_view name() const override { return name_; }
  std::string_view status_text() const override { return status_text_; }

 private:
  int fd_;
  Transport transport_;
  std::string name_;
  KeyboardProbeModel model_;
  TerminalKeyDecoder terminal_;
  std::vector<InputEvent> events_;
  std::vector<std::uint8_t> buffer_;
  hal::TimestampUs last_key_us_ = -1;
  std::uint32_t sequence_ = 0;
  bool failed_ = false;
  std::string status_text_;
  struct SavedTerminal;
  std::unique_ptr<SavedTerminal> saved_terminal_;
};

// Opens `device` (an evdev node) or, when empty, the controlling terminal in raw mode. Throws
// std::runtime_error naming the device and the cause (no such device, permission) otherwise.
std::unique_ptr<KeyboardProbe> open_keyboard_probe(const std::string& device,
                                                   const KeyboardProbeSettings& settings);

}  // namespace ultrasim::drivers::keyboard
