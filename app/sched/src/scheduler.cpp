#include "ultrasim/sched/scheduler.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace ultrasim::sched {

namespace {

std::string name_of(const TaskSpec& spec) {
  return spec.name.empty() ? std::string("(unnamed)") : std::string(spec.name);
}

void check(const TaskSpec& spec) {
  if (spec.run == nullptr) {
    throw std::invalid_argument("Scheduler: task " + name_of(spec) + ": no run function");
  }
  if (spec.budget_us <= 0) {
    throw std::invalid_argument("Scheduler: task " + name_of(spec) + ": budget_us must be > 0");
  }
  if (spec.expect_from_last_runs < 0 || spec.expect_from_last_runs > kMaxExpectedRuns) {
    throw std::invalid_argument("Scheduler: task " + name_of(spec) +
                                ": expect_from_last_runs must be in [0, " +
                                std::to_string(kMaxExpectedRuns) + "]");
  }
  if (spec.expect_from_last_runs > 0 && !spec.mandatory && spec.max_consecutive_slips == 0) {
    // Expected to take more than any frame leaves, it would never run again to learn otherwise.
    throw std::invalid_argument("Scheduler: task " + name_of(spec) +
                                ": an optional task expected from its last runs needs "
                                "max_consecutive_slips > 0");
  }
  if (!(spec.rate_hz >= 0.0) || !std::isfinite(spec.rate_hz)) {
    throw std::invalid_argument("Scheduler: task " + name_of(spec) +
                                ": rate_hz must be finite and >= 0");
  }
}

// Ticks between runs: the loop rate over the task's, rounded, at least 1.
std::int64_t period_ticks(const TaskSpec& spec, double loop_rate_hz) {
  if (spec.rate_hz <= 0.0 || spec.rate_hz >= loop_rate_hz) return 1;
  return std::max<std::int64_t>(1, std::llround(loop_rate_hz / spec.rate_hz));
}

}  // namespace

Scheduler::Scheduler(const hal::Clock& clock, std::span<const TaskSpec> table,
                     const SchedulerSettings& settings)
    : clock_(clock), settings_(settings), frame_(settings.frame_budget_us) {
  if (!(settings.loop_rate_hz > 0.0) || !std::isfinite(settings.loop_rate_hz)) {
    throw std::invalid_argument("Scheduler: loop_rate_hz must be > 0");
  }
  if (settings.frame_budget_us <= 0) {
    throw std::invalid_argument("Scheduler: frame_budget_us must be > 0");
  }
  for (const TaskSpec& spec : table) {
    check(spec);
    slots_.push_back({spec, period_ticks(spec, settings.loop_rate_hz), 0});
  }
  std::stable_sort(slots_.begin(), slots_.end(),
                   [](const Slot& a, const Slot& b) { return a.spec.priority < b.spec.priority; });
  stats_.reserve(slots_.size());
  for (const Slot& slot : slots_) {
    stats_.push_back({slot.spec.name, FrameTimeStats(slot.spec.budget_us), 0, 0, 0});
  }
}

TickReport Scheduler::tick() {
  TickReport report;
  const hal::TimestampUs start_us = clock_.now_us();
  // Time the mandatory tasks due later in this tick will need is not given to optional ones.
  std::int64_t reserved_us = 0;
  for (std::size_t i = slots_.size(); i-- > 0;) {
    slots_[i].reserved_after_us = reserved_us;
    if (slots_[i].spec.mandatory && ticks_ >= slots_[i].next_due_tick) {
      reserved_us += std::min(slots_[i].spec.budget_us, expected_us(slots_[i]));
    }
  }
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    Slot& slot = slots_[i];
    if (ticks_ < slot.next_due_tick) continue;
    TaskStats& stats = stats_[i];
    const hal::TimestampUs task_start_us = clock_.now_us();
    const std::int64_t time_left_us =
        settings_.frame_budget_us - (task_start_us - start_us) - slot.reserved_after_us;
    const bool starved = slot.spec.max_consecutive_slips > 0 &&
                         slot.consecutive_slips >= slot.spec.max_consecutive_slips;
    if (!slot.spec.mandatory && expected_us(slot) > time_left_us) {
      if (!starved) {
        // Stays due: it is tried again next tick, and every skipped due tick is a slip.
        ++stats.slips;
        ++slot.consecutive_slips;
        ++report.tasks_skipped;
        continue;
      }
      ++stats.forced_runs;
    }
    slot.consecutive_slips = 0;
    slot.spec.run(slot.spec.context, TaskTick{ticks_, start_us, time_left_us});
    const std::int64_t took_us = clock_.now_us() - task_start_us;
    remember_run(slot, took_us);
    stats.time.record(took_us);
    stats.last_run_tick = ticks_;
    stats.last_run_us = took_us;
    ++stats.runs;
    if (took_us > slot.spec.budget_us) ++stats.overruns;
    ++report.tasks_run;
    slot.next_due_tick = ticks_ + slot.period_ticks;
  }
  report.duration_us = clock_.now_us() - start_us;
  report.deadline_missed = report.duration_us > settings_.frame_budget_us;
  frame_.record(report.duration_us);
  ++ticks_;
  return report;
}

std::int64_t Scheduler::expected_us(const Slot& slot) {
  const int runs = slot.spec.expect_from_last_runs;
  if (runs == 0 || slot.recent_count < runs) return slot.spec.budget_us;
  std::array<std::int64_t, kMaxExpectedRuns> sorted = slot.recent_us;
  const auto recent = std::span(sorted).first(static_cast<std::size_t>(runs));
  // The 90th percentile: the smallest value that at least 90 % of the runs do not exceed.
  const auto rank = static_cast<std::ptrdiff_t>((9 * runs + 9) / 10 - 1);
  std::ranges::nth_element(recent, recent.begin() + rank);
  return recent[static_cast<std::size_t>(rank)];
}

void Scheduler::remember_run(Slot& slot, std::int64_t took_us) {
  const int runs = slot.spec.expect_from_last_runs;
  if (runs == 0) return;
  slot.recent_us[static_cast<std::size_t>(slot.recent_next)] = took_us;
  slot.recent_next = (slot.recent_next + 1) % runs;
  slot.recent_count = std::min(slot.recent_count + 1, runs);
}

const TaskStats* Scheduler::find(std::string_view name) const {
  for (const TaskStats& s : stats_) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

}  // namespace ultrasim::sched
