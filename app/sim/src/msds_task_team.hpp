#pragma once

// A frame's parallel stages on one JobSystem::run() (internal to MsdsEngine).
//
// Why: an explicit MSDS frame is 20 short steps, each a parallel stage of ~50 µs (and the implicit
// solver's CG iterations are shorter still). A JobSystem run() wakes its workers each time, which
// on the 2-core target VM costs ~40 µs: one run per stage made two threads slower than one.
//
// How: run(lead) starts one task per thread. The first task to start leads: it runs lead(), the
// frame's serial code, which calls for_each() for each parallel stage. The other tasks help: they
// wait (spinning) for a stage, claim its items alongside the lead, and return when the lead is
// done. The lead never waits for a helper to start, only for items a running thread has claimed,
// so a JobSystem that runs the tasks one after another still finishes (the lead does every item,
// then the helpers find the run over). Items are claimed dynamically; callers make each item's
// result independent of which thread runs it (fixed partitions, sums in item order).

#include <atomic>
#include <cstdint>

#include "ultrasim/hal/job_system.hpp"

namespace ultrasim::sim::msds_detail {

class TaskTeam {
 public:
  explicit TaskTeam(hal::JobSystem* jobs) : jobs_(jobs) {}
  TaskTeam(const TaskTeam&) = delete;
  TaskTeam& operator=(const TaskTeam&) = delete;

  // Runs lead() once, with the job system's threads as helpers for its for_each() stages (inline
  // without jobs or with one thread). Not reentrant. Does not allocate.
  template <typename Lead>
  void run(Lead&& lead) {
    using L = std::remove_reference_t<Lead>;
    run_erased([](void* context) { (*static_cast<L*>(context))(); },
               const_cast<void*>(static_cast<const void*>(&lead)));
  }

  // body(i) for every i in [0, count), spread over the team inside run(), inline outside it;
  // returns when all are done.
  template <typename Body>
  void for_each(int count, Body&& body) {
    using B = std::remove_reference_t<Body>;
    for_each_erased(
        count, [](void* context, int i) { (*static_cast<B*>(context))(i); },
        const_cast<void*>(static_cast<const void*>(&body)));
  }

  // Threads a run() spreads stages over (1 without jobs).
  int thread_count() const;

 private:
  using Item = void (*)(void* context, int index);

  void run_erased(void (*lead)(void*), void* context);
  void for_each_erased(int count, Item item, void* context);
  // One task of a run: the first to start leads, the others help.
  void member();
  void help();
  // Claims and runs items of stage `epoch` until none is left or the stage has moved on.
  void work_on(std::uint32_t epoch);

  // A stage's items. Stages alternate between two of these: a helper that was slow to see a
  // stage change may still read the last stage's while the lead writes the next one's.
  struct Stage {
    std::atomic<Item> item{nullptr};
    std::atomic<void*> context{nullptr};
    std::atomic<int> count{0};
  };

  hal::JobSystem* jobs_;
  bool running_ = false;  // inside run(), on the lead's thread
  void (*lead_)(void*) = nullptr;
  void* lead_context_ = nullptr;
  std::uint32_t run_start_epoch_ = 0;  // the stage epoch before the run's first stage
  std::atomic<bool> lead_taken_{false};
  std::atomic<bool> finished_{false};
  // The current stage: its epoch (high 32 bits; its items are stages_[epoch % 2]) and next
  // unclaimed item (low 32 bits). A claim is a compare-exchange of the whole word, so a helper
  // that slept through a stage change cannot take an item of the wrong stage. A successful claim
  // also proves the stage unfinished, so stages_[epoch % 2] had not been reused when read.
  std::atomic<std::uint64_t> stage_{0};
  Stage stages_[2];
  std::atomic<int> items_done_{0};
};

}  // namespace ultrasim::sim::msds_detail
