// StitchedVolume's frame: the due sub-volumes stepped in batches within the frame's time, shared
// over the frame's exchanges, then the frame kept, cut back or refused.

#include <algorithm>
#include <mutex>
#include <type_traits>

#include "stitched_frame_time.hpp"
#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/msds.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

// start_frame keeps the caller's function by address: the same type, or a temporary.
static_assert(std::is_same_v<StitchedVolume::TimeLeftUs, StitchedFrameTime::TimeLeftUs>);

namespace {

// A corotational sub-volume out of the probe's reach whose update cannot be held waits for a
// frame with the time for it at most this many times between two updates (with an update due
// every other frame, four seconds; between its due frames it may step and solve the last warped
// system). At 60 the seam presses' neighbours took their update whatever the time within a
// press and hold of 2.2 s, and the simulation's p99 rose from 5.2-5.3 to 5.3-6.2 ms (at 120:
// 5.3-5.5 ms).
constexpr int kMostTimesAnUpdateWaits = 120;

}  // namespace

EngineStepStats StitchedVolume::step(const ProbeCollider* probe, double frame_dt_s) {
  return step_within(probe, frame_dt_s, {});
}

EngineStepStats StitchedVolume::step_within(const ProbeCollider* probe, double frame_dt_s,
                                            const StepBudget& may_continue) {
  return step_sharing(probe, frame_dt_s, may_continue, {});
}

EngineStepStats StitchedVolume::step_sharing(const ProbeCollider* probe, double frame_dt_s,
                                             const StepBudget& may_continue,
                                             const TimeLeftUs& time_left_us) {
  for (auto& sub : subs_) sub.stepped = sub.moved = false;
  // The coarse step first, from the shape the last frame left: the sub-volumes' own steps then
  // smooth what it leaves near the probe and at the seams, and the contacts are decided on their
  // answer, not on the coarse field's.
  correct_coarsely();
  // The sub-volumes that step whatever the time: those in the probe's reach (touched), and those
  // the last frame's torn seam left standing.
  const int touched = plan_frame(probe);
  const int in_reach = static_cast<int>(
      std::ranges::count_if(subs_, [](const SubVolume& sub) { return sub.touched; }));
  const int batch = jobs_ != nullptr ? std::max(1, jobs_->thread_count()) : 1;
  // The sub-volumes the probe may touch always step: skipping one would let the probe pass
  // through the tissue. So do those a torn seam left standing last frame.
  // The first exchange picks which sub-volumes step this frame; the others step the same ones.
  ++exchange_count_;  // the first exchange's
  for (int s = 0; s < sub_volume_count(); ++s) {
    const CorotationalFem* fem = subs_[s].corotational;
    update_forced_[s] = fem != nullptr && fem->update_forced_at(exchange_count_);
  }
  // The sub-volumes take the frame's budget as one piece does: the CG methods iterate while the
  // frame has time (warm-started, they catch up over the next frames), the explicit MSDS steps
  // while there is time and retries a rejected frame with smaller steps only while there is. The
  // large case's touched sub-volumes took 22 ms (PCG FEM, 20 iterations each) and 34 ms (implicit
  // MSDS) of the simulation's 4 ms at p50 with full solves. The sub-volumes step on the job
  // system's threads, and the budget is one clock for them all.
  StepBudget sub_budget;
  if (may_continue) {
    sub_budget = [this, &may_continue] {
      std::lock_guard lock(budget_mutex_);
      return may_continue();
    };
  }
  // With the time left known, the frame's time is shared out evenly over the exchanges and, in
  // the first, over the batches due that fit at their least cost (one CG iteration, the explicit
  // MSDS's fixed steps: last frame's), the touched ones first; a batch stops its own work once its
  // share is spent (StitchedFrameTime).
  const int scheduled = static_cast<int>(schedule_.size());
  StitchedFrameTime& time = *frame_time_;
  time.start_frame(may_continue, time_left_us, exchanges_per_frame_, (touched + batch - 1) / batch,
                   (scheduled - touched + batch - 1) / batch);
  const bool shares = time.shares();
  // A frame with no time for all its exchanges covers its time in fewer, longer parts: the
  // MSDS's sub-volumes integrate that many parts' simulated time in each (the PCG FEM's static
  // answer does not depend on it). The large case's six touched sub-volumes took 3.4-3.9 ms at
  // their least in two exchanges of the PCG FEM, and the frame's work after the steps 0.7 more,
  // over the simulation's 4 ms on 99 of 571 frames by 0.3-2.2 ms.
  const int parts = time.exchanges();
  const double part_dt_s = frame_dt_s / parts;
  const int stretch = exchanges_per_frame_ / parts;
  const int due_batches = time.due_batches();
  // The due sub-volumes (all without a budget) in batches that share the fewest seam nodes.
  const int must_step = order_into_batches(
      touched, shares ? std::min(scheduled, due_batches * batch) : scheduled, batch);
  int updates_held = 0;  // over the frame's batches and exchanges
  // Steps schedule_[first, first + count) with `reserve_us` kept back from its share.
  const auto run_batch = [&](int first, int count, std::int64_t reserve_us, bool first_part) {
    const std::span<const int> subs = std::span(schedule_).subspan(first, count);
    const bool hold_updates = time.begin_batch(reserve_us);
    step_batch(subs, probe, part_dt_s, stretch, first_part,
               shares ? time.batch_budget() : sub_budget, hold_updates);
    const auto held = static_cast<int>(std::ranges::count_if(subs, [this](int s) {
      return subs_[s].corotational != nullptr && subs_[s].corotational->update_held();
    }));
    updates_held += held;
    time.end_batch(held > 0, std::ranges::any_of(subs, [this](int s) {
                     return subs_[s].corotational != nullptr &&
                            subs_[s].corotational->warped_system_updated();
                   }));
  };
  int next = 0;
  int b = 0;
  const auto step_next_batch = [&](int end) {
    const int count = std::min(batch, end - next);
    run_batch(next, count, time.first_part_reserve_us(b), true);
    next += count;
    ++b;
  };
  // The sub-volumes known to step in the first exchange: those that must. A batch that fits
  // later is marked as it starts.
  std::fill(steps_later_in_exchange_.begin(), steps_later_in_exchange_.end(), 0);
  for (int i = 0; i < must_step; ++i) steps_later_in_exchange_[schedule_[i]] = 1;
  while (next < must_step) step_next_batch(must_step);
  // A corotational sub-volume whose due update can be held no more (update_forced_at) costs a
  // batch with an update, not a batch at its least: once such a batch no longer fits, the rest
  // of the frame steps the others and it waits for a frame with the time (under the large
  // case's seam presses an extra sub-volume's forced update made 43 of the 89 frames whose
  // simulation took over 5 ms), kMostTimesAnUpdateWaits times at most between two updates (a
  // press that never leaves the time would otherwise keep its rotations as they were for good).
  int end = scheduled;
  const auto defer_forced_updates = [&] {
    if (time.update_batch_fits()) return;
    batched_.clear();  // free after order_into_batches: the deferred, in order
    int kept = next;
    for (int i = next; i < end; ++i) {
      SubVolume& sub = subs_[schedule_[i]];
      if (update_forced_[schedule_[i]] && sub.times_update_waited < kMostTimesAnUpdateWaits) {
        ++sub.times_update_waited;  // once a frame: past `end` it is not looked at again
        batched_.push_back(schedule_[i]);
      } else {
        schedule_[kept++] = schedule_[i];
      }
    }
    std::copy(batched_.begin(), batched_.end(), schedule_.begin() + kept);
    end = kept;
  };
  while (next < end && time.another_batch_fits(b)) {
    defer_forced_updates();
    if (next < end) step_next_batch(end);
  }
  // The later exchanges step the same sub-volumes, each batch its even share of the part's time.
  const int batches_stepped = (next + batch - 1) / batch;
  for (int part = 1; part < parts; ++part) {
    ++exchange_count_;
    time.start_later_part(part);
    for (int i = 0; i < next; ++i) steps_later_in_exchange_[schedule_[i]] = 1;
    for (int j = 0; j < batches_stepped; ++j) {
      run_batch(j * batch, std::min(batch, next - j * batch),
                time.later_part_reserve_us(part, j, batches_stepped), false);
    }
  }
  time.end_steps();
  stats_.exchanges = parts;  // before the seams' update: a seam's move is per exchange
  stats_.exchanges_left_out = exchanges_per_frame_ - parts;
  const EngineStepStats out =
      settle_frame(std::span(schedule_).first(next), in_reach, next < scheduled, may_continue);
  time.end_frame();
  stats_.sub_volumes_touched = in_reach;
  stats_.sub_volumes_stepped = next;
  stats_.sub_volumes_deferred = 0;
  for (const auto& sub : subs_) stats_.sub_volumes_deferred += !sub.stepped && !sub.asleep;
  stats_.updates_held = updates_held;
  return out;
}

void StitchedVolume::step_batch(std::span<const int> subs, const ProbeCollider* probe,
                                double frame_dt_s, int stretch, bool first_part,
                                const StepBudget& budget, bool hold_updates) {
  // Anchors first, from positions no sub-volume of the batch has moved yet: the batch's steps
  // are then independent and run in parallel.
  for (const int s : subs) steps_later_in_exchange_[s] = 1;
  hal::parallel_for(jobs_, static_cast<int>(subs.size()),
                    [&](int i) { refresh_anchors(subs[i], probe); });
  for (const int s : subs) steps_later_in_exchange_[s] = 0;  // stepping now: twins lead no more
  auto step_one = [&](int i) {
    SubVolume& sub = subs_[subs[i]];
    if (first_part) {
      const auto before = sub.engine->deformed_positions_mm();
      std::copy(before.begin(), before.end(), sub.previous_positions_mm.begin());
    }
    if (sub.corotational != nullptr) {
      sub.corotational->set_update_clock(exchange_count_);
      if (hold_updates) sub.corotational->hold_next_update();
    }
    if (sub.msds != nullptr && stretch > 1) sub.msds->stretch_next_frame(stretch);
    const EngineStepStats s = sub.engine->step_within(probe, frame_dt_s, budget);
    if (first_part) {
      sub.last_stats = s;
    } else {
      // The frame's stats: work summed, the latest contact, the worst of the rest.
      EngineStepStats& f = sub.last_stats;
      f.iterations += s.iterations;
      f.relative_residual = s.relative_residual;
      f.contact_nodes = s.contact_nodes;
      f.contact_force_n = s.contact_force_n;
      f.inverted_tets = std::max(f.inverted_tets, s.inverted_tets);
      if (!f.diverged) f.cause = s.cause;  // the frame's first
      f.diverged = f.diverged || s.diverged;
      f.recovery = worse_recovery(f.recovery, s.recovery);
    }
    take_positions(sub);
    sub.stepped = sub.moved = true;
  };
  hal::parallel_for(jobs_, static_cast<int>(subs.size()), step_one);
}

}  // namespace ultrasim::sim
