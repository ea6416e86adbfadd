#pragma once

#include <atomic>
#include <thread>

#include "ultrasim/hal/job_system.hpp"

namespace ultrasim::testing {

// A JobSystem on two threads: the caller and one helper started per run, taking task indices
// from a shared counter, so tasks run interleaved and out of order. For tests that check parallel
// work gives the serial answer (a thread per run is fine in a test).
class TwoThreadJobs final : public hal::JobSystem {
 public:
  int thread_count() const override { return 2; }
  void run(int task_count, void (*task)(void*, int), void* context) override {
    std::atomic<int> next{0};
    const auto drain = [&] {
      for (int i = next.fetch_add(1); i < task_count; i = next.fetch_add(1)) task(context, i);
    };
    std::thread helper(drain);
    drain();
    helper.join();
  }
};

}  // namespace ultrasim::testing
