#include "ultrasim/kiosk/frame_loop.hpp"

#include <algorithm>

namespace ultrasim::kiosk {

FrameLoop::FrameLoop(Session& session, FrameRenderer& renderer, const hal::Clock& clock,
                     const sched::FrameBudgetSettings& budgets)
    : session_(&session),
      renderer_(renderer),
      clock_(clock),
      simulation_budget_us_(budgets.simulation_budget_us),
      scheduler_(clock, table(budgets), {60.0, budgets.budget_us}) {}

std::array<sched::TaskSpec, 4> FrameLoop::table(const sched::FrameBudgetSettings& budgets) {
  // Every task at the loop's rate; the order is the data flow (DESIGN.md §2). The B-scan is what
  // the trainee watches: after two skipped frames it runs whatever the time (it may lag, never
  // freeze); the 3D view may wait longer.
  return {{
      {kSimulation, 0.0, budgets.simulation_budget_us, 0, true, &FrameLoop::simulate, this, 0},
      {kBscan, 0.0, budgets.bscan_budget_us, 1, false, &FrameLoop::bscan, this, 2},
      {kView, 0.0, budgets.view_budget_us, 2, false, &FrameLoop::view, this, 5},
      {kRender, 0.0, budgets.render_budget_us, 3, true, &FrameLoop::render, this, 0},
  }};
}

sched::TickReport FrameLoop::run_frame(const std::optional<hal::PoseSample>& sample) {
  sample_ = sample;
  return scheduler_.tick();
}

void FrameLoop::simulate(void* self, const sched::TaskTick& tick) {
  auto* loop = static_cast<FrameLoop*>(self);
  // The method spends at most its budget, and never the time reserved for the render: past the
  // deadline only its work that cannot wait still runs (Session::simulate).
  const std::int64_t allowed_us =
      std::clamp<std::int64_t>(tick.time_left_us, 0, loop->simulation_budget_us_);
  loop->outcome_ = loop->session_->simulate(loop->sample_, loop->clock_.now_us() + allowed_us);
}

void FrameLoop::bscan(void* self, const sched::TaskTick&) {
  static_cast<FrameLoop*>(self)->session_->update_bscan();
}

void FrameLoop::view(void* self, const sched::TaskTick&) {
  static_cast<FrameLoop*>(self)->session_->update_view();
}

void FrameLoop::render(void* self, const sched::TaskTick& tick) {
  auto* loop = static_cast<FrameLoop*>(self);
  loop->renderer_.render(*loop->session_, tick.tick_index);
}

}  // namespace ultrasim::kiosk
