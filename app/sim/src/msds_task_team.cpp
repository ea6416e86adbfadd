#include "msds_task_team.hpp"

#include <algorithm>

namespace ultrasim::sim::msds_detail {

namespace {

// A spinning thread's hint to the core (lets its sibling hyperthread run; saves power).
inline void spin_pause() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

std::uint32_t epoch_of(std::uint64_t stage) {
  return static_cast<std::uint32_t>(stage >> 32);
}

std::uint32_t next_item_of(std::uint64_t stage) {
  return static_cast<std::uint32_t>(stage);
}

}  // namespace

int TaskTeam::thread_count() const {
  return jobs_ != nullptr ? std::max(jobs_->thread_count(), 1) : 1;
}

void TaskTeam::run_erased(void (*lead)(void*), void* context) {
  if (thread_count() < 2) {
    lead(context);
    return;
  }
  lead_ = lead;
  lead_context_ = context;
  lead_taken_.store(false, std::memory_order_relaxed);
  finished_.store(false, std::memory_order_relaxed);
  run_start_epoch_ = epoch_of(stage_.load(std::memory_order_relaxed));
  jobs_->run(
      thread_count(), [](void* team, int) { static_cast<TaskTeam*>(team)->member(); }, this);
}

void TaskTeam::member() {
  if (lead_taken_.exchange(true, std::memory_order_acq_rel)) {
    help();
    return;
  }
  // Helpers spin until the lead is done, whatever happens to it.
  struct Finish {
    TaskTeam& team;
    ~Finish() {
      team.running_ = false;
      team.finished_.store(true, std::memory_order_release);
    }
  } finish{*this};
  running_ = true;
  lead_(lead_context_);
}

void TaskTeam::help() {
  // A helper that starts late joins the stage under way: every epoch past the run's start is one
  // of its stages.
  std::uint32_t seen = run_start_epoch_;
  while (!finished_.load(std::memory_order_acquire)) {
    const std::uint32_t epoch = epoch_of(stage_.load(std::memory_order_acquire));
    if (epoch == seen) {
      spin_pause();
      continue;
    }
    work_on(epoch);
    seen = epoch;
  }
}

void TaskTeam::work_on(std::uint32_t epoch) {
  // Called after an acquire load showed `epoch`: its fields are visible.
  const Stage& s = stages_[epoch % 2];
  const Item item = s.item.load(std::memory_order_relaxed);
  void* const context = s.context.load(std::memory_order_relaxed);
  const auto count = static_cast<std::uint32_t>(s.count.load(std::memory_order_relaxed));
  std::uint64_t stage = stage_.load(std::memory_order_acquire);
  while (epoch_of(stage) == epoch && next_item_of(stage) < count) {
    if (!stage_.compare_exchange_weak(stage, stage + 1, std::memory_order_acq_rel)) continue;
    item(context, static_cast<int>(next_item_of(stage)));
    items_done_.fetch_add(1, std::memory_order_release);
    stage = stage_.load(std::memory_order_acquire);
  }
}

void TaskTeam::for_each_erased(int count, Item item, void* context) {
  if (!running_ || count < 2) {
    for (int i = 0; i < count; ++i) item(context, i);
    return;
  }
  // Publish the stage: its fields first, then the new epoch (release) that helpers wait for.
  // Every item of the last stage is done, so no helper still holds a claim on it.
  const std::uint32_t epoch = epoch_of(stage_.load(std::memory_order_relaxed)) + 1;
  Stage& s = stages_[epoch % 2];
  s.item.store(item, std::memory_order_relaxed);
  s.context.store(context, std::memory_order_relaxed);
  s.count.store(count, std::memory_order_relaxed);
  items_done_.store(0, std::memory_order_relaxed);
  stage_.store(static_cast<std::uint64_t>(epoch) << 32, std::memory_order_release);
  work_on(epoch);
  // What is left are items a running helper has claimed: it will finish them.
  while (items_done_.load(std::memory_order_acquire) < count) spin_pause();
}

}  // namespace ultrasim::sim::msds_detail
