#include "ultrasim/kiosk/frame_loop.hpp"

#include <algorithm>

namespace ultrasim::kiosk {

FrameLoop::FrameLoop(Session& session, FrameRenderer& renderer, const hal::Clock& clock,
                     const sched::FrameBudgetSettings& budgets)
    : session_(&session),
      renderer_(renderer),
      clock_(clock),
      simulation_budget_us_(budgets.simulation_budget_us),
      render_budget_us_(budgets.render_budget_us),
      render_capped_(budgets.budget_us),
      scheduler_(clock, table(budgets), {60.0, budgets.budget_us}) {}

std::array<sched::TaskSpec, 4> FrameLoop::table(const sched::FrameBudgetSettings& budgets) {
  // Every task at the loop's rate; the order is the data flow (DESIGN.md §2). The B-scan is what
  // the trainee watches: after two skipped frames it runs whatever the time (it may lag, never
  // freeze); the 3D view may wait longer. Each is expected to take what 90 % of its last 30 runs
  // took: the B-scan and the view start only where that fits, and the rendering keeps back that
  // (at most its budget: on a GPU it takes a third of its 9 ms).
  constexpr int kExpectFromRuns = 30;
  return {{
      {kSimulation, 0.0, budgets.simulation_budget_us, 0, true, &FrameLoop::simulate, this, 0},
      {kBscan, 0.0, budgets.bscan_budget_us, 1, false, &FrameLoop::bscan, this, 2, kExpectFromRuns},
      {kView, 0.0, budgets.view_budget_us, 2, false, &FrameLoop::view, this, 5, kExpectFromRuns},
      {kRender, 0.0, budgets.render_budget_us, 3, true, &FrameLoop::render, this, 0,
       kExpectFromRuns},
  }};
}

sched::TickReport FrameLoop::run_frame(const std::optional<hal::PoseSample>& sample,
                                       std::int64_t sample_age_us) {
  sample_ = sample;
  sample_age_us_ = std::max<std::int64_t>(sample_age_us, 0);
  frame_start_us_ = clock_.now_us();
  last_render_us_ = 0;
  const sched::TickReport report = scheduler_.tick();
  last_render_capped_us_ =
      report.duration_us - std::max<std::int64_t>(last_render_us_ - render_budget_us_, 0);
  render_capped_.record(last_render_capped_us_);
  return report;
}

FrameLoop::OtherTasksUs FrameLoop::last_other_tasks_us() const {
  const auto ran_last_tick = [this](const char* name) -> std::int64_t {
    const sched::TaskStats* stats = scheduler_.find(name);
    return stats != nullptr && stats->last_run_tick == scheduler_.tick_count() - 1
               ? stats->last_run_us
               : 0;
  };
  return {ran_last_tick(kBscan), ran_last_tick(kView),
          std::min(ran_last_tick(kRender), render_budget_us_)};
}

void FrameLoop::simulate(void* self, const sched::TaskTick& tick) {
  auto* loop = static_cast<FrameLoop*>(self);
  // The method spends at most its budget, and never the time reserved for the render: past the
  // deadline only its work that cannot wait still runs (Session::simulate).
  const std::int64_t allowed_us =
      std::clamp<std::int64_t>(tick.time_left_us, 0, loop->simulation_budget_us_);
  const hal::TimestampUs start_us = loop->clock_.now_us();
  loop->outcome_ = loop->session_->simulate(loop->sample_, start_us + allowed_us);
  loop->last_simulation_us_ = loop->clock_.now_us() - start_us;
}

void FrameLoop::bscan(void* self, const sched::TaskTick&) {
  static_cast<FrameLoop*>(self)->session_->update_bscan();
}

void FrameLoop::view(void* self, const sched::TaskTick&) {
  static_cast<FrameLoop*>(self)->session_->update_view();
}

void FrameLoop::render(void* self, const sched::TaskTick& tick) {
  auto* loop = static_cast<FrameLoop*>(self);
  const hal::TimestampUs start_us = loop->clock_.now_us();
  loop->renderer_.render(*loop->session_, tick.tick_index);
  loop->last_render_us_ = loop->clock_.now_us() - start_us;
  // Only a frame that took a new pose shows a probe position this new.
  if (loop->sample_ && !loop->outcome_.pose_rejected) {
    loop->probe_to_photon_.record(loop->sample_age_us_ + loop->clock_.now_us() -
                                  loop->frame_start_us_);
  }
}

}  // namespace ultrasim::kiosk
