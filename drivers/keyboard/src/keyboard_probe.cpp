#include "ultrasim/drivers/keyboard/keyboard_probe.hpp"

#include <errno.h>
#include <fcntl.h>
#include <linux/input.h>
#include <termios.h>
#include <unistd.h>

#include <cstring>
#include <stdexcept>

namespace ultrasim::drivers::keyboard {

namespace {

// A terminal reports presses only: a key counts as held until its auto-repeat stops this long.
constexpr hal::TimestampUs kTerminalHoldUs = 150'000;

}  // namespace

struct KeyboardProbe::SavedTerminal {
  termios mode;
};

KeyboardProbe::KeyboardProbe(int fd, Transport transport, std::string name,
                             const KeyboardProbeSettings& settings)
    : fd_(fd), transport_(transport), name_(std::move(name)), model_(settings) {
  ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) | O_NONBLOCK);
  events_.reserve(64);
  buffer_.resize(64 * sizeof(input_event));
  status_text_.reserve(96);
  termios mode{};
  if (transport_ == Transport::kTerminal && ::tcgetattr(fd_, &mode) == 0) {
    saved_terminal_ = std::make_unique<SavedTerminal>(SavedTerminal{mode});
    cfmakeraw(&mode);
    mode.c_oflag |= OPOST;  // keep the log's line endings
    mode.c_lflag |= ISIG;   // Ctrl-C still stops the kiosk
    ::tcsetattr(fd_, TCSANOW, &mode);
  }
}

KeyboardProbe::~KeyboardProbe() {
  if (saved_terminal_) ::tcsetattr(fd_, TCSANOW, &saved_terminal_->mode);
  ::close(fd_);
}

std::optional<hal::PoseSample> KeyboardProbe::latest(hal::TimestampUs now_us) {
  events_.clear();
  while (!failed_) {
    const ssize_t n = ::read(fd_, buffer_.data(), buffer_.size());
    if (n > 0) {
      if (transport_ == Transport::kTerminal) {
        terminal_.feed(buffer_.data(), static_cast<std::size_t>(n), events_);
      } else {
        for (std::size_t i = 0; i + sizeof(input_event) <= static_cast<std::size_t>(n);
             i += sizeof(input_event)) {
          input_event e;
          std::memcpy(&e, buffer_.data() + i, sizeof e);
          if (e.type == EV_KEY) events_.push_back({InputEvent::Kind::kKey, e.code, e.value});
          if (e.type == EV_REL) events_.push_back({InputEvent::Kind::kRelative, e.code, e.value});
        }
      }
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) break;
    // End of file, or the device went away (ENODEV): keep the last pose, say so.
    failed_ = true;
    status_text_.assign(name_).append(n == 0 ? ": closed" : ": gone (unplugged?)");
  }
  // A terminal's keys: the ones that stopped repeating are up.
  if (transport_ == Transport::kTerminal) {
    if (!events_.empty()) {
      model_.release_all();
      last_key_us_ = now_us;
    } else if (last_key_us_ >= 0 && now_us - last_key_us_ > kTerminalHoldUs) {
      model_.release_all();
    }
  }
  // Hold each key from now: advance over the time before the new events with the old ones.
  model_.advance(now_us);
  for (const auto& e : events_) model_.apply(e);
  hal::PoseSample sample;
  sample.timestamp_us = now_us;
  sample.sequence = sequence_++;
  sample.position_mm = model_.position_mm();
  sample.orientation = model_.orientation();
  sample.health = failed_ ? hal::PoseHealth::kFault : hal::PoseHealth::kOk;
  return sample;
}

std::unique_ptr<KeyboardProbe> open_keyboard_probe(const std::string& device,
                                                   const KeyboardProbeSettings& settings) {
  const std::string path = device.empty() ? std::string("/dev/tty") : device;
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    throw std::runtime_error("keyboard probe: " + path + ": " + std::strerror(errno) +
                             (device.empty() ? " (no terminal: set [probe] keyboard_device)" : ""));
  }
  return std::make_unique<KeyboardProbe>(
      fd, device.empty() ? KeyboardProbe::Transport::kTerminal : KeyboardProbe::Transport::kEvdev,
      "keyboard " + path, settings);
}

}  // namespace ultrasim::drivers::keyboard
