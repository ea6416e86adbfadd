#include "ultrasim/drivers/posix/thread_pool.hpp"

#include <algorithm>
#include <latch>

namespace ultrasim::drivers::posix {

ThreadPool::ThreadPool(int thread_count, const RealtimeRequest* realtime,
                       std::chrono::microseconds poll_before_sleep)
    : poll_before_sleep_(poll_before_sleep) {
  const int workers = std::max(thread_count, 1) - 1;
  workers_.reserve(static_cast<std::size_t>(workers));
  if (realtime != nullptr) worker_realtime_.resize(static_cast<std::size_t>(workers));
  std::latch set_up(workers);
  for (int i = 0; i < workers; ++i) {
    workers_.emplace_back([this, realtime, i, &set_up] {
      if (realtime != nullptr) {
        worker_realtime_[static_cast<std::size_t>(i)] = make_this_thread_realtime(*realtime, i + 1);
      }
      set_up.count_down();
      worker_loop();
    });
  }
  set_up.wait();  // worker_realtime_ is complete, and `set_up` outlives every use of it
}

ThreadPool::~ThreadPool() {
  gate_.stop();
  for (auto& w : workers_) w.join();
}

void ThreadPool::drain() {
  for (int i = next_.fetch_add(1, std::memory_order_relaxed); i < task_count_;
       i = next_.fetch_add(1, std::memory_order_relaxed)) {
    task_(context_, i);
  }
}

void ThreadPool::worker_loop() {
  std::uint64_t seen = 0;
  while (gate_.join_next(seen, poll_before_sleep_)) {
    drain();
    gate_.leave();
  }
}

void ThreadPool::run(int task_count, void (*task)(void*, int), void* context) {
  if (task_count <= 0) return;
  if (workers_.empty() || task_count == 1) {
    for (int i = 0; i < task_count; ++i) task(context, i);
    return;
  }
  task_ = task;
  context_ = context;
  task_count_ = task_count;
  next_.store(0, std::memory_order_relaxed);
  gate_.open();
  drain();
  // Every worker inside the batch must leave it before the next run() may overwrite it; one
  // still asleep finds it closed.
  gate_.close_and_wait();
}

}  // namespace ultrasim::drivers::posix
