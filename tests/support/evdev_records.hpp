#pragma once

// Evdev records for tests: what a keyboard, mouse or touch screen node delivers, written into a
// pipe or FIFO that stands in for the device.

#include <linux/input.h>
#include <unistd.h>

#include <cstdint>

namespace ultrasim::testing {

// Writes one struct input_event (time zero) to `fd`; whether all of it went.
inline bool write_input_event(int fd, std::uint16_t type, std::uint16_t code, std::int32_t value) {
  input_event e{};
  e.type = type;
  e.code = code;
  e.value = value;
  return ::write(fd, &e, sizeof e) == static_cast<ssize_t>(sizeof e);
}

}  // namespace ultrasim::testing
