#include "ultrasim/drivers/posix/worker_gate.hpp"

namespace ultrasim::drivers::posix {

void WorkerGate::open() {
  {
    std::lock_guard lock(mutex_);
    ++batch_;
    open_ = true;
  }
  opened_.notify_all();
}

void WorkerGate::close_and_wait() {
  std::unique_lock lock(mutex_);
  open_ = false;
  emptied_.wait(lock, [&] { return inside_ == 0; });
}

bool WorkerGate::join_next(std::uint64_t& seen) {
  std::unique_lock lock(mutex_);
  // A batch closed before this worker came is over: the next one is its.
  opened_.wait(lock, [&] { return stopping_ || (open_ && batch_ != seen); });
  if (stopping_) return false;
  seen = batch_;
  ++inside_;
  return true;
}

void WorkerGate::leave() {
  bool last = false;
  {
    std::lock_guard lock(mutex_);
    last = --inside_ == 0;
  }
  if (last) emptied_.notify_one();
}

void WorkerGate::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  opened_.notify_all();
}

}  // namespace ultrasim::drivers::posix
