#pragma once

// The fixed-budget frame scheduler, in the manner of ArduPilot's AP_Scheduler: a static task
// table (rate, budget, priority), run once per tick in priority order while the frame's budget
// lasts. A task that is due but does not fit in the time left (after reserving the budgets of
// the mandatory tasks still to come, such as the render hand-off) is skipped, counted as a slip
// and tried again on the next tick; a task that runs past its own budget is counted as an overrun.
// The frame never waits for a late task: it trades work for latency, never latency for work.
// Time comes only from the injected hal::Clock, so tests drive it with a ManualClock.

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "ultrasim/hal/clock.hpp"
#include "ultrasim/sched/frame_time_stats.hpp"

namespace ultrasim::sched {

// What a running task is told about its tick.
struct TaskTick {
  std::int64_t tick_index = 0;
  hal::TimestampUs tick_start_us = 0;
  // Frame budget left when the task started, less what the mandatory tasks still to run this
  // tick keep back (their budgets, or what they are expected to take: expect_from_last_runs) (may
  // be ≤ 0 for a mandatory task). A task that can stop early (sub-volume solves) spends at most
  // min(its budget, this).
  std::int64_t time_left_us = 0;
};

// One row of the static task table. Definition struct: fill it, the scheduler copies it.
struct TaskSpec {
  std::string_view name;  // for stats and reports; must outlive the scheduler (a literal)
  // Runs every round(loop_rate_hz / rate_hz) ticks; 0 or ≥ the loop rate: every tick.
  double rate_hz = 0.0;
  // The most the task should take, µs: it is started only when this much of the frame is left
  // (or what it is expected to take, expect_from_last_runs; mandatory tasks always start) and
  // counted as an overrun when it takes longer. > 0.
  std::int64_t budget_us = 1;
  // Lower runs first within a tick; ties keep table order.
  int priority = 0;
  // Runs on every due tick even when the frame's budget is spent (input, render hand-off).
  bool mandatory = false;
  // The work: called on the ticking thread with `context`. Must not be null.
  void (*run)(void* context, const TaskTick& tick) = nullptr;
  void* context = nullptr;
  // An optional task skipped this many due ticks in a row runs on the next one whatever the
  // time (counted in TaskStats::forced_runs): the B-scan may lag, never freeze. 0: no limit.
  int max_consecutive_slips = 0;
  // What the task is expected to take: its budget (0), or the 90th percentile of its last
  // this-many runs (1..kMaxExpectedRuns; the longest of fewer than ten; its budget until it has
  // run that often), so that one slow run among 30 is not expected again (a machine's hiccup
  // would keep an optional task to its forced runs until 30 more had passed). An optional task
  // starts only if that fits in the time left (and must have max_consecutive_slips > 0, or one
  // slow spell would keep it from running ever again); a mandatory one keeps that back, at most
  // its budget, from the optional tasks before it. The kiosk's B-scan takes 4 ms of its 3 on the
  // large case, and its rendering 3 ms of its 9 on a GPU: by budgets alone the B-scan started
  // where it did not fit, or found no room beside a rendering that needed a third of it.
  int expect_from_last_runs = 0;
};

inline constexpr int kMaxExpectedRuns = 64;

struct SchedulerSettings {
  double loop_rate_hz = 60.0;             // ticks per second
  std::int64_t frame_budget_us = 16'667;  // work per tick; a tick past it is a deadline miss
};

// One task's accounting since the scheduler started.
struct TaskStats {
  std::string_view name;
  FrameTimeStats time;              // duration of each run, against the task's budget
  std::int64_t runs = 0;            // times it ran
  std::int64_t slips = 0;           // due ticks it was skipped for lack of time
  std::int64_t overruns = 0;        // runs that took longer than its budget
  std::int64_t forced_runs = 0;     // runs without the time, after max_consecutive_slips slips
  std::int64_t last_run_tick = -1;  // the tick of its latest run (-1: none yet)
  std::int64_t last_run_us = 0;     // and how long that run took
};

// What one tick did.
struct TickReport {
  std::int64_t duration_us = 0;
  int tasks_run = 0;
  int tasks_skipped = 0;
  bool deadline_missed = false;  // the tick's work took longer than the frame budget
};

class Scheduler {
 public:
  // Validates the table (every task with a run function and a positive budget, rates > 0 or 0)
  // and sorts it by priority. Throws std::invalid_argument naming the task. Allocates.
  Scheduler(const hal::Clock& clock, std::span<const TaskSpec> table,
            const SchedulerSettings& settings = {});

  // Runs one tick: each due task in priority order if it fits in the time left. Call once per
  // frame from one thread. Does not allocate.
  TickReport tick();

  std::int64_t tick_count() const { return ticks_; }
  // Tick durations against the frame budget (deadline misses, percentiles).
  const FrameTimeStats& frame_stats() const { return frame_; }
  // Per task, in priority order (the order tasks run in).
  std::span<const TaskStats> task_stats() const { return stats_; }
  // The stats of the task named `name`, or nullptr.
  const TaskStats* find(std::string_view name) const;

 private:
  struct Slot {
    TaskSpec spec;
    std::int64_t period_ticks = 1;
    std::int64_t next_due_tick = 0;
    std::int64_t reserved_after_us = 0;  // this tick: reserves of due mandatory tasks after it
    int consecutive_slips = 0;
    // The last runs' durations (expect_from_last_runs of them, a ring) and how many are known.
    std::array<std::int64_t, kMaxExpectedRuns> recent_us{};
    int recent_count = 0;
    int recent_next = 0;
  };
  // What the task is expected to take (TaskSpec::expect_from_last_runs).
  static std::int64_t expected_us(const Slot& slot);
  static void remember_run(Slot& slot, std::int64_t took_us);

  const hal::Clock& clock_;
  SchedulerSettings settings_;
  std::vector<Slot> slots_;
  std::vector<TaskStats> stats_;
  FrameTimeStats frame_;
  std::int64_t ticks_ = 0;
};

}  // namespace ultrasim::sched
