#pragma once

#include <type_traits>
#include <utility>

namespace ultrasim::hal {

// Runs a frame's parallel work on the machine's worker threads. Modules never start threads of
// their own: they expose work that splits into independent pieces (row bands, tet ranges) and the
// composition root hands them a JobSystem (DESIGN.md §3).
class JobSystem {
 public:
  virtual ~JobSystem() = default;

  // Threads that run tasks, the caller included (1: everything runs on the caller).
  virtual int thread_count() const = 0;

  // Calls task(context, i) once for every i in [0, task_count), spread over the threads, and
  // returns when all have finished. The caller runs tasks too. Does not allocate. Call from one
  // thread at a time (the frame thread); tasks must not call run() themselves.
  virtual void run(int task_count, void (*task)(void* context, int index), void* context) = 0;

  // Work longer than any frame (a solve of ~30 ms), for a thread of its own at the lowest
  // priority that takes only the time the frame's threads leave: queues task(context) to run
  // once there and returns true, or returns false and queues nothing when there is no such
  // thread (the default) or a task is already queued or running. The caller learns from the
  // task itself that it has run and keeps `context` alive until then. Does not allocate.
  virtual bool post_background(void (* /*task*/)(void* context), void* /*context*/) {
    return false;
  }
};

// parallel_for(jobs, n, [&](int i) { ... }): the same with a lambda, without allocating.
template <typename F>
void parallel_for(JobSystem& jobs, int task_count, F&& f) {
  using Task = std::remove_reference_t<F>;  // F is an lvalue reference for a named lambda
  jobs.run(
      task_count, [](void* context, int index) { (*static_cast<Task*>(context))(index); },
      const_cast<void*>(static_cast<const void*>(&f)));
}

// The same where a job system may be missing: on `jobs` when there is one with more than one
// thread and more than one task, otherwise in order on the caller (engines built without one:
// tests, tools).
template <typename F>
void parallel_for(JobSystem* jobs, int task_count, F&& f) {
  if (jobs != nullptr && jobs->thread_count() > 1 && task_count > 1) {
    parallel_for(*jobs, task_count, f);
  } else {
    for (int i = 0; i < task_count; ++i) f(i);
  }
}

// A JobSystem with no threads: every task runs on the caller, in order.
class InlineJobSystem final : public JobSystem {
 public:
  int thread_count() const override { return 1; }
  void run(int task_count, void (*task)(void*, int), void* context) override {
    for (int i = 0; i < task_count; ++i) task(context, i);
  }
};

}  // namespace ultrasim::hal
