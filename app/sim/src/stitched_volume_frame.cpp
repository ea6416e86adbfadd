// StitchedVolume's frame: the due sub-volumes stepped in batches within the frame's time, shared
// over the frame's exchanges, then the frame kept, cut back or refused.

#include <algorithm>
#include <mutex>

#include "ultrasim/sim/corotational_fem.hpp"
#include "ultrasim/sim/stitched_volume.hpp"

namespace ultrasim::sim {

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
  const int parts = exchanges_per_frame_;
  const double part_dt_s = frame_dt_s / parts;
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
  // With the time left known, the frame's time is shared out evenly over the batches due that fit
  // at their least cost (one CG iteration, the explicit MSDS's fixed steps: last frame's), the
  // touched ones first; a batch stops its own work once its share is spent, and the time the work
  // after the steps took last frame is kept back. Without sharing, the touched sub-volumes' CG
  // took the whole frame and their neighbours never stepped: the seams between them opened (the
  // large case's sweep-press: 0.4-2.5 mm; 0.13-0.17 shared). One pointer captured: no allocation.
  // A batch's work does not end at its first "no": an implicit MSDS's CG stops, then its next
  // step computes every spring's force and block and one iteration more (the large case: about
  // as long as its CG had). What the batches did after their first "no" last frame is kept back
  // too, so that the batch ends within its share instead of starting its tail there.
  struct BatchShare {
    StitchedVolume* self;
    const StepBudget* frame;
    const TimeLeftUs* time_left_us;
    std::int64_t reserve_us;
    std::int64_t left_at_first_question_us;  // -1 until the batch's first question
    std::int64_t left_at_first_no_us;        // -1 until the batch's first "no"
  } share{this, &may_continue, &time_left_us, 0, -1, -1};
  const StepBudget share_budget = [&share] {
    std::lock_guard lock(share.self->budget_mutex_);
    const std::int64_t left_us = (*share.time_left_us)();
    if (share.left_at_first_question_us < 0) share.left_at_first_question_us = left_us;
    const bool yes = (*share.frame)() && left_us > share.reserve_us + share.self->batch_tail_us_;
    if (!yes && share.left_at_first_no_us < 0) share.left_at_first_no_us = left_us;
    return yes;
  };
  const int scheduled = static_cast<int>(schedule_.size());
  const int touched_batches = (touched + batch - 1) / batch;
  const int other_batches = (scheduled - touched + batch - 1) / batch;
  const bool shares = may_continue && time_left_us;
  // The time left is shared over the frame's exchanges evenly: this first one plans its batches
  // on its part and keeps the others' back.
  const std::int64_t left_at_start_us =
      shares ? std::max<std::int64_t>(time_left_us() - after_steps_us_, 0) / parts : 0;
  const std::int64_t later_parts_us = left_at_start_us * (parts - 1);
  const int batches_that_fit =
      shares && batch_cost_us_ > 0 ? static_cast<int>(left_at_start_us / batch_cost_us_) : 1;
  // At least one: a frame with nothing touched still shares its time among those that run.
  const int due_batches = std::max(
      1, touched_batches + std::clamp(batches_that_fit - touched_batches, 0, other_batches));
  // The due sub-volumes (all without a budget) in batches that share the fewest seam nodes.
  const int must_step = order_into_batches(
      touched, shares ? std::min(scheduled, due_batches * batch) : scheduled, batch);
  std::int64_t batch_cost_us = 0;
  std::int64_t update_batch_cost_us = -1;  // -1: no batch brought a warped system up to date
  bool cost_measured = false;              // by a batch that held no update
  int updates_held = 0;                    // over the frame's batches and exchanges
  std::int64_t batch_tail_us = -1;
  // Steps schedule_[first, first + count) with `reserve_us` kept back from its share, and
  // measures the batch's least cost and its tail in every exchange: with one implicit MSDS step
  // a part, a later exchange's batch may be the only one told no.
  const auto run_batch = [&](int first, int count, std::int64_t reserve_us, bool first_part) {
    share.reserve_us = reserve_us;
    share.left_at_first_question_us = share.left_at_first_no_us = -1;
    const std::int64_t left_before_us = shares ? time_left_us() : 0;
    // A batch whose share (left less what is kept back) is no more than what a batch with an
    // update took (a full frame, or a late one; at least a batch's least cost) has its
    // corotational sub-volumes hold their due updates: the time the rotations would take goes to
    // the CG, whose one iteration a frame is what kept the seam presses' forces at 1.6 times the
    // solved run's (1.2 held; [stitching] corotational_update_turns_held). Held only where the
    // share did not cover the least cost, a first batch of six touched took its updates in a
    // share of a third of the frame and ran past it by 0.5-0.7 ms.
    const bool hold_updates =
        shares && left_before_us - reserve_us <= std::max(batch_cost_us_, update_batch_cost_us_);
    const std::span<const int> subs = std::span(schedule_).subspan(first, count);
    step_batch(subs, probe, part_dt_s, first_part, shares ? share_budget : sub_budget,
               hold_updates);
    const auto held = static_cast<int>(std::ranges::count_if(subs, [this](int s) {
      return subs_[s].corotational != nullptr && subs_[s].corotational->update_held();
    }));
    updates_held += held;
    if (!shares) return;
    const std::int64_t left_at_end_us = time_left_us();
    // Up to the first question, or the whole batch if none asked (no further work wanted). Not
    // from a batch that held an update: its cost without it would plan more batches next frame,
    // whose shares would not cover the updates taken whatever the time.
    const std::int64_t left_after_us =
        share.left_at_first_question_us >= 0 ? share.left_at_first_question_us : left_at_end_us;
    const bool updated = std::ranges::any_of(subs, [this](int s) {
      return subs_[s].corotational != nullptr && subs_[s].corotational->warped_system_updated();
    });
    if (updated) {
      update_batch_cost_us = std::max(update_batch_cost_us, left_before_us - left_after_us);
    }
    if (held == 0) batch_cost_us = std::max(batch_cost_us, left_before_us - left_after_us);
    cost_measured = cost_measured || held == 0;
    if (share.left_at_first_no_us >= 0) {
      batch_tail_us = std::max(batch_tail_us, share.left_at_first_no_us - left_at_end_us);
    }
  };
  int next = 0;
  int b = 0;
  const auto step_next_batch = [&](int end) {
    const int count = std::min(batch, end - next);
    const int batches_after = std::max(due_batches - 1 - b, 0);
    run_batch(next, count,
              after_steps_us_ + later_parts_us + left_at_start_us * batches_after / due_batches,
              true);
    next += count;
    ++b;
  };
  while (next < must_step) step_next_batch(must_step);
  // A planned batch while time is left (its share was sized to fit it); a further one only if one
  // at its least cost still ends in time.
  const auto another_batch_fits = [&] {
    if (!may_continue) return true;
    if (!shares) return may_continue();
    const std::lock_guard lock(budget_mutex_);
    return time_left_us() >
           (b < due_batches ? 0 : batch_cost_us_) + after_steps_us_ + later_parts_us;
  };
  // A corotational sub-volume whose due update can be held no more (update_forced_at) costs a
  // batch with an update, not a batch at its least: once such a batch no longer fits, the rest
  // of the frame steps the others and it waits for a frame with the time (under the large
  // case's seam presses an extra sub-volume's forced update made 43 of the 89 frames whose
  // simulation took over 5 ms), kMostTimesAnUpdateWaits times at most between two updates (a
  // press that never leaves the time would otherwise keep its rotations as they were for good).
  int end = scheduled;
  const auto defer_forced_updates = [&] {
    if (!shares || update_batch_cost_us_ <= 0 ||
        time_left_us() > update_batch_cost_us_ + after_steps_us_ + later_parts_us) {
      return;
    }
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
  while (next < end && another_batch_fits()) {
    defer_forced_updates();
    if (next < end) step_next_batch(end);
  }
  // The later exchanges step the same sub-volumes, each batch its even share of the part's time
  // (the part's: what is left over the parts to go).
  const int batches_stepped = (next + batch - 1) / batch;
  for (int part = 1; part < parts; ++part) {
    ++exchange_count_;
    const std::int64_t part_us =
        shares ? std::max<std::int64_t>(time_left_us() - after_steps_us_, 0) / (parts - part) : 0;
    for (int j = 0; j < batches_stepped; ++j) {
      run_batch(j * batch, std::min(batch, next - j * batch),
                after_steps_us_ + part_us * (parts - part - 1) +
                    part_us * (batches_stepped - 1 - j) / batches_stepped,
                false);
    }
  }
  if (shares && cost_measured) batch_cost_us_ = batch_cost_us;
  if (shares && update_batch_cost_us >= 0) update_batch_cost_us_ = update_batch_cost_us;
  // Kept from the last frame where a batch was told no (one with time to spare says nothing).
  if (shares && batch_tail_us >= 0) batch_tail_us_ = batch_tail_us;
  const std::int64_t left_after_steps_us = shares ? time_left_us() : 0;
  const EngineStepStats out =
      settle_frame(std::span(schedule_).first(next), in_reach, next < scheduled, may_continue);
  if (shares) after_steps_us_ = std::max<std::int64_t>(left_after_steps_us - time_left_us(), 0);
  stats_.sub_volumes_touched = in_reach;
  stats_.sub_volumes_stepped = next;
  stats_.sub_volumes_deferred = 0;
  for (const auto& sub : subs_) stats_.sub_volumes_deferred += !sub.stepped && !sub.asleep;
  stats_.updates_held = updates_held;
  return out;
}

void StitchedVolume::step_batch(std::span<const int> subs, const ProbeCollider* probe,
                                double frame_dt_s, bool first_part, const StepBudget& budget,
                                bool hold_updates) {
  // Anchors first, from positions no sub-volume of the batch has moved yet: the batch's steps
  // are then independent and run in parallel.
  hal::parallel_for(jobs_, static_cast<int>(subs.size()),
                    [&](int i) { refresh_anchors(subs[i], probe); });
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
