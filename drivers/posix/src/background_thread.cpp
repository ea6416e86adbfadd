#include "ultrasim/drivers/posix/background_thread.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>

#include <latch>

namespace ultrasim::drivers::posix {

namespace {

// SCHED_IDLE needs no privilege (a thread may always lower itself); nice 19 is the fallback.
bool lower_this_thread() {
  sched_param param{};
  param.sched_priority = 0;
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) == 0) return true;
  setpriority(PRIO_PROCESS, 0, 19);  // on Linux, this thread's nice value
  return false;
}

}  // namespace

BackgroundThread::BackgroundThread() {
  std::latch lowered(1);
  thread_ = std::thread([this, &lowered] {
    idle_priority_ = lower_this_thread();
    lowered.count_down();
    loop();
  });
  lowered.wait();  // idle_priority_ is set, and `lowered` outlives every use of it
}

BackgroundThread::~BackgroundThread() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

bool BackgroundThread::post(void (*task)(void*), void* context) {
  {
    std::lock_guard lock(mutex_);
    if (task_ != nullptr || stopping_) return false;
    task_ = task;
    context_ = context;
  }
  wake_.notify_one();
  return true;
}

void BackgroundThread::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return task_ == nullptr; });
}

void BackgroundThread::loop() {
  for (;;) {
    void (*task)(void*) = nullptr;
    void* context = nullptr;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || task_ != nullptr; });
      if (task_ == nullptr) return;  // stopping, nothing left: a posted task always runs
      task = task_;
      context = context_;
    }
    task(context);
    {
      std::lock_guard lock(mutex_);
      task_ = nullptr;
    }
    idle_.notify_all();
  }
}

}  // namespace ultrasim::drivers::posix
