#include "ultrasim/drivers/socketcan/socketcan_bus.hpp"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace ultrasim::drivers::socketcan {

namespace {

std::runtime_error system_error(const std::string& interface, const char* what) {
  return std::runtime_error("SocketCAN " + interface + ": " + what + ": " + std::strerror(errno));
}

std::int64_t realtime_now_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

}  // namespace

SocketCanBus::SocketCanBus(const std::string& interface, const hal::Clock& clock)
    : interface_(interface), clock_(clock) {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    throw std::runtime_error("SocketCAN: bad interface name '" + interface + "'");
  }
  fd_ = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) throw system_error(interface, "cannot open a CAN socket");
  try {
    ifreq request{};
    std::strncpy(request.ifr_name, interface.c_str(), IFNAMSIZ - 1);
    if (ioctl(fd_, SIOCGIFINDEX, &request) < 0) throw system_error(interface, "no such interface");
    const int on = 1;
    // Kernel receive timestamps, and the receive queue's drop counter with every frame.
    if (setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) < 0) {
      throw system_error(interface, "SO_TIMESTAMP");
    }
    if (setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) {
      throw system_error(interface, "SO_RXQ_OVFL");
    }
    const can_err_mask_t errors = CAN_ERR_MASK;
    if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) < 0) {
      throw system_error(interface, "CAN_RAW_ERR_FILTER");
    }
    sockaddr_can address{};
    address.can_family = AF_CAN;
    address.can_ifindex = request.ifr_ifindex;
    if (bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) < 0) {
      throw system_error(interface, "bind");
    }
  } catch (...) {
    close(fd_);
    throw;
  }
}

SocketCanBus::~SocketCanBus() {
  if (fd_ >= 0) close(fd_);
}

bool SocketCanBus::send(const hal::CanFrame& frame, hal::TimestampUs deadline_us) {
  if (!frame.well_formed() || clock_.now_us() > deadline_us ||
      stats_.state == hal::CanBusState::kBusOff) {
    ++stats_.tx_failures;
    return false;
  }
  can_frame out{};
  out.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0u) | (frame.remote ? CAN_RTR_FLAG : 0u);
  out.can_dlc = frame.length;
  std::memcpy(out.data, frame.data.data(), frame.remote ? 0 : frame.length);
  // Non-blocking: a full transmit queue refuses the frame rather than wait past the deadline.
  if (write(fd_, &out, sizeof out) != static_cast<ssize_t>(sizeof out)) {
    ++stats_.tx_failures;
    return false;
  }
  ++stats_.tx_frames;
  return true;
}

bool SocketCanBus::receive(hal::ReceivedCanFrame& out) {
  for (;;) {
    can_frame in{};
    iovec io{&in, sizeof in};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(std::uint32_t))];
    msghdr message{};
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control;
    message.msg_controllen = sizeof control;
    const ssize_t n = recvmsg(fd_, &message, MSG_DONTWAIT);
    if (n < 0) return false;  // EAGAIN: nothing waiting (other errors: nothing to give either)
    if (n != static_cast<ssize_t>(sizeof in)) continue;  // not a classic frame (CAN FD): skip
    std::int64_t kernel_realtime_us = -1;
    for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SO_TIMESTAMP) {
        timeval tv{};
        std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
        kernel_realtime_us = static_cast<std::int64_t>(tv.tv_sec) * 1'000'000 + tv.tv_usec;
      } else if (c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t dropped = 0;
        std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
        stats_.rx_overflows = dropped;  // the socket's running total
      }
    }
    if ((in.can_id & CAN_ERR_FLAG) != 0) {
      apply_error_frame(stats_, in.can_id, std::span<const std::uint8_t, 8>(in.data, 8));
      continue;
    }
    out.frame = hal::CanFrame{};
    out.frame.extended = (in.can_id & CAN_EFF_FLAG) != 0;
    out.frame.remote = (in.can_id & CAN_RTR_FLAG) != 0;
    out.frame.id = in.can_id & (out.frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    out.frame.length = std::min<std::uint8_t>(in.can_dlc, 8);
    std::memcpy(out.frame.data.data(), in.data, out.frame.length);
    // The kernel stamps arrival on the wall clock: carry its age over to our monotonic clock.
    const hal::TimestampUs now = clock_.now_us();
    out.timestamp_us =
        kernel_realtime_us < 0
            ? now
            : now - std::max<std::int64_t>(0, realtime_now_us() - kernel_realtime_us);
    ++stats_.rx_frames;
    return true;
  }
}

void apply_error_frame(hal::CanBusStats& stats, std::uint32_t can_id,
                       std::span<const std::uint8_t, 8> data) {
  ++stats.error_frames;
  if ((can_id & CAN_ERR_BUSOFF) != 0) {
    if (stats.state != hal::CanBusState::kBusOff) ++stats.bus_off_events;
    stats.state = hal::CanBusState::kBusOff;
    return;
  }
  // The controller recovered from bus off (restart-ms, or "ip link set ... type can restart").
  if ((can_id & CAN_ERR_RESTARTED) != 0) {
    stats.state = hal::CanBusState::kErrorActive;
    return;
  }
  if ((can_id & CAN_ERR_CRTL) != 0) {
    const std::uint8_t crtl = data[1];
    if ((crtl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) {
      stats.state = hal::CanBusState::kErrorPassive;
    } else if ((crtl & (CAN_ERR_CRTL_ACTIVE | CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) !=
               0) {
      // Back below the passive threshold (a warning level is still error active).
      stats.state = hal::CanBusState::kErrorActive;
    }
  }
}

}  // namespace ultrasim::drivers::socketcan
