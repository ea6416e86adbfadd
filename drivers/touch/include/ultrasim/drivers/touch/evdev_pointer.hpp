#pragma once

#include <memory>
#include <string>
#include <vector>

#include "ultrasim/drivers/touch/pointer_decoder.hpp"
#include "ultrasim/hal/pointer_input.hpp"

namespace ultrasim::drivers::touch {

// The trainer's touch screen or mouse as a hal::PointerSource over an evdev file descriptor it
// reads without blocking. A device that goes away (unplugged) stops giving events and says so in
// status_text(); the kiosk goes on without it.
class EvdevPointer final : public hal::PointerSource {
 public:
  // Takes ownership of `fd` (closed on destruction).
  EvdevPointer(int fd, std::string name, const PointerDecoder& decoder);
  ~EvdevPointer() override;
  EvdevPointer(const EvdevPointer&) = delete;
  EvdevPointer& operator=(const EvdevPointer&) = delete;

  std::span<const hal::PointerEvent> poll() override;
  std::string_view name() const override { return name_; }
  std::string_view status_text() const override { return status_text_; }

 private:
  int fd_;
  std::string name_;
  PointerDecoder decoder_;
  std::vector<std::uint8_t> buffer_;
  std::vector<hal::PointerEvent> events_;
  bool failed_ = false;
  std::string status_text_;
};

// Opens `device` (/dev/input/eventN) for a screen of the given size, reading a touch screen's
// axis ranges from the device. Throws std::runtime_error naming the device and the cause (no
// such device, permission) otherwise.
std::unique_ptr<EvdevPointer> open_evdev_pointer(const std::string& device, int screen_width_px,
                                                 int screen_height_px);

}  // namespace ultrasim::drivers::touch
