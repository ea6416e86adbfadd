#include "ultrasim/drivers/touch/evdev_pointer.hpp"

#include <fcntl.h>
#include <linux/input.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace ultrasim::drivers::touch {

EvdevPointer::EvdevPointer(int fd, std::string name, const PointerDecoder& decoder)
    : fd_(fd), name_(std::move(name)), decoder_(decoder) {
  buffer_.resize(64 * sizeof(input_event));
  events_.reserve(64);
}

EvdevPointer::~EvdevPointer() {
  ::close(fd_);
}

std::span<const hal::PointerEvent> EvdevPointer::poll() {
  events_.clear();
  while (!failed_) {
    const ssize_t n = ::read(fd_, buffer_.data(), buffer_.size());
    if (n > 0) {
      for (std::size_t i = 0; i + sizeof(input_event) <= static_cast<std::size_t>(n);
           i += sizeof(input_event)) {
        input_event e;
        std::memcpy(&e, buffer_.data() + i, sizeof e);
        decoder_.feed({e.type, e.code, e.value}, events_);
      }
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) break;
    // End of file, or the device went away (ENODEV): no more touches; say so.
    failed_ = true;
    status_text_.assign(name_).append(n == 0 ? ": closed" : ": gone (unplugged?)");
  }
  return events_;
}

std::unique_ptr<EvdevPointer> open_evdev_pointer(const std::string& device, int screen_width_px,
                                                 int screen_height_px) {
  const int fd = ::open(device.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    throw std::runtime_error(device +
                             ": cannot open the touch screen or mouse: " + std::strerror(errno));
  }
  // A touch screen reports its axes' ranges; a mouse has none (EVIOCGABS fails): relative.
  const auto range = [fd](unsigned axis, unsigned mt_axis) {
    input_absinfo info{};
    if (::ioctl(fd, EVIOCGABS(mt_axis), &info) == 0 && info.maximum > info.minimum) {
      return AxisRange{info.minimum, info.maximum};
    }
    if (::ioctl(fd, EVIOCGABS(axis), &info) == 0 && info.maximum > info.minimum) {
      return AxisRange{info.minimum, info.maximum};
    }
    return AxisRange{};
  };
  const PointerDecoder decoder(screen_width_px, screen_height_px, range(ABS_X, ABS_MT_POSITION_X),
                               range(ABS_Y, ABS_MT_POSITION_Y));
  return std::make_unique<EvdevPointer>(fd, device, decoder);
}

}  // namespace ultrasim::drivers::touch
