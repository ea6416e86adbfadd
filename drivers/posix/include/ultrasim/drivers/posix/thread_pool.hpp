#pragma once

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "ultrasim/drivers/posix/background_thread.hpp"
#include "ultrasim/drivers/posix/realtime.hpp"
#include "ultrasim/drivers/posix/worker_gate.hpp"
#include "ultrasim/hal/job_system.hpp"

namespace ultrasim::drivers::posix {

// hal::JobSystem on a fixed set of worker threads started once. run() wakes the workers, hands
// out task indices through an atomic counter (the caller takes its share too, and all of them
// while no worker has come) and waits until every task has finished, not for workers that took
// none (WorkerGate). A worker done with a run watches for the next a while before it sleeps.
// Nothing is allocated per run. post_background() goes to one more thread at idle priority
// (BackgroundThread), never realtime.
class ThreadPool final : public hal::JobSystem {
 public:
  // How long a worker that finished a run watches for the next before it sleeps
  // (WorkerGate::join_next): longer than the gaps between a frame's runs, short against the frame.
  // A SCHED_FIFO worker (--realtime) yields only to threads of its own priority: for this long
  // after each frame's last run, normal threads on its core (llvmpipe's) wait.
  static constexpr std::chrono::microseconds kPollBeforeSleep{200};

  // thread_count includes the calling thread: ThreadPool(2) starts one worker. Values < 1 → 1.
  // With `realtime`, worker i becomes frame thread i + 1 (make_this_thread_realtime) before the
  // constructor returns; the caller is frame thread 0 and sets itself up.
  explicit ThreadPool(int thread_count, const RealtimeRequest* realtime = nullptr,
                      std::chrono::microseconds poll_before_sleep = kPollBeforeSleep);
  ~ThreadPool() override;
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int thread_count() const override { return static_cast<int>(workers_.size()) + 1; }
  // What each worker got of the realtime request (empty without one).
  const std::vector<ThreadRealtime>& worker_realtime() const { return worker_realtime_; }
  void run(int task_count, void (*task)(void*, int), void* context) override;
  bool post_background(void (*task)(void*), void* context) override {
    return background_.post(task, context);
  }
  BackgroundThread& background() { return background_; }

 private:
  void worker_loop();
  void drain();  // runs tasks of the current batch until none is left

  std::chrono::microseconds poll_before_sleep_;
  std::vector<std::thread> workers_;
  std::vector<ThreadRealtime> worker_realtime_;
  WorkerGate gate_;
  // The current batch, written before the gate opens, read by the workers that join it.
  void (*task_)(void*, int) = nullptr;
  void* context_ = nullptr;
  int task_count_ = 0;
  std::atomic<int> next_{0};
  // Last: destroyed (its task finished) before the state above.
  BackgroundThread background_;
};

}  // namespace ultrasim::drivers::posix
