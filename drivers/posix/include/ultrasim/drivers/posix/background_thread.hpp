#pragma once

#include <condition_variable>
#include <mutex>
#include <thread>

namespace ultrasim::drivers::posix {

// One thread for work longer than a frame (hal::JobSystem::post_background), started at
// construction and lowered to SCHED_IDLE (nice 19 where that is refused), so it runs only on
// time the frame's threads leave. It holds one task at a time; nothing is allocated per task.
// A posted task always runs: the destructor waits for it.
class BackgroundThread {
 public:
  BackgroundThread();
  ~BackgroundThread();
  BackgroundThread(const BackgroundThread&) = delete;
  BackgroundThread& operator=(const BackgroundThread&) = delete;

  // Queues task(context); false when a task is queued or running, or the thread is stopping.
  bool post(void (*task)(void*), void* context);
  // Whether the thread got SCHED_IDLE (false: nice 19, or neither was granted).
  bool idle_priority() const { return idle_priority_; }
  // Blocks until no task is queued or running (tests, tools).
  void wait_idle();

 private:
  void loop();

  std::mutex mutex_;
  std::condition_variable wake_, idle_;
  void (*task_)(void*) = nullptr;  // queued or running
  void* context_ = nullptr;
  bool stopping_ = false;
  bool idle_priority_ = false;
  std::thread thread_;  // last: started once the members above exist
};

}  // namespace ultrasim::drivers::posix
