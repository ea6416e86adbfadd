// A stitched frame's time shared over its exchanges and batches (StitchedVolume::step_sharing).
//
// Without sharing, the touched sub-volumes' CG took the whole frame and their neighbours never
// stepped: the seams between them opened (the large case's sweep-press: 0.4-2.5 mm; 0.13-0.17
// shared). A batch's work does not end at its first "no": an implicit MSDS's CG stops, then its
// next step computes every spring's force and block and one iteration more (the large case: about
// as long as its CG had). What the batches did after their first "no" last frame is kept back
// too, so that a batch ends within its share instead of starting its tail there.

#include "stitched_frame_time.hpp"

#include <algorithm>

namespace ultrasim::sim {

StitchedFrameTime::StitchedFrameTime(std::mutex& clock_mutex)
    : clock_mutex_(clock_mutex), batch_budget_([this] { return ask(); }) {}

void StitchedFrameTime::start_frame(const StepBudget& may_continue, const TimeLeftUs& time_left_us,
                                    int parts, int touched_batches, int other_batches) {
  may_continue_ = &may_continue;
  time_left_us_ = &time_left_us;
  shares_ = may_continue && time_left_us;
  const std::int64_t left_us =
      shares_ ? std::max<std::int64_t>(time_left_us() - after_steps_us_, 0) : 0;
  exchanges_ = shares_ ? exchanges_that_fit(left_us, parts, touched_batches) : parts;
  // Evenly over the frame's exchanges: the first plans its batches on its part and keeps the
  // others' back.
  left_at_start_us_ = left_us / exchanges_;
  later_parts_us_ = left_at_start_us_ * (exchanges_ - 1);
  const int batches_that_fit =
      shares_ && batch_cost_us_ > 0 ? static_cast<int>(left_at_start_us_ / least_batch_us()) : 1;
  due_batches_ = std::max(
      1, touched_batches + std::clamp(batches_that_fit - touched_batches, 0, other_batches));
  frame_batch_cost_us_ = 0;
  frame_update_batch_cost_us_ = -1;
  cost_measured_ = false;
  frame_batch_tail_us_ = -1;
}

int StitchedFrameTime::exchanges_that_fit(std::int64_t left_us, int parts,
                                          int touched_batches) const {
  if (batch_cost_us_ <= 0) return parts;  // nothing measured yet
  for (int exchanges = parts; exchanges > 1; --exchanges) {
    if (parts % exchanges == 0 &&
        static_cast<std::int64_t>(touched_batches) * exchanges * least_batch_us() <= left_us) {
      return exchanges;
    }
  }
  return 1;
}

std::int64_t StitchedFrameTime::first_part_reserve_us(int b) const {
  const int batches_after = std::max(due_batches_ - 1 - b, 0);
  return after_steps_us_ + later_parts_us_ + left_at_start_us_ * batches_after / due_batches_;
}

void StitchedFrameTime::start_later_part(int part) {
  part_us_ = shares_ ? std::max<std::int64_t>((*time_left_us_)() - after_steps_us_, 0) /
                           (exchanges_ - part)
                     : 0;
}

std::int64_t StitchedFrameTime::later_part_reserve_us(int part, int j, int batches) const {
  return after_steps_us_ + part_us_ * (exchanges_ - part - 1) +
         part_us_ * (batches - 1 - j) / batches;
}

bool StitchedFrameTime::begin_batch(std::int64_t reserve_us) {
  reserve_us_ = reserve_us;
  left_at_first_question_us_ = left_at_first_no_us_ = -1;
  left_before_us_ = shares_ ? (*time_left_us_)() : 0;
  // A batch whose share (left less what is kept back) is no more than what a batch with an
  // update took (a full frame, or a late one; at least a batch's least cost) has its
  // corotational sub-volumes hold their due updates: the time the rotations would take goes to
  // the CG, whose one iteration a frame is what kept the seam presses' forces at 1.6 times the
  // solved run's (1.2 held; [stitching] corotational_update_turns_held). Held only where the
  // share did not cover the least cost, a first batch of six touched took its updates in a
  // share of a third of the frame and ran past it by 0.5-0.7 ms.
  return shares_ && left_before_us_ - reserve_us <= std::max(batch_cost_us_, update_batch_cost_us_);
}

bool StitchedFrameTime::ask() {
  std::lock_guard lock(clock_mutex_);
  const std::int64_t left_us = (*time_left_us_)();
  if (left_at_first_question_us_ < 0) left_at_first_question_us_ = left_us;
  const bool yes = (*may_continue_)() && left_us > reserve_us_ + batch_tail_us_;
  if (!yes && left_at_first_no_us_ < 0) left_at_first_no_us_ = left_us;
  return yes;
}

void StitchedFrameTime::end_batch(bool held_an_update, bool updated) {
  if (!shares_) return;
  const std::int64_t left_at_end_us = (*time_left_us_)();
  // Up to the first question, or the whole batch if none asked (no further work wanted). Not
  // from a batch that held an update: its cost without it would plan more batches next frame,
  // whose shares would not cover the updates taken whatever the time. Measured in every
  // exchange: with one implicit MSDS step a part, a later exchange's batch may be the only one
  // told no.
  const std::int64_t left_after_us =
      left_at_first_question_us_ >= 0 ? left_at_first_question_us_ : left_at_end_us;
  if (updated) {
    frame_update_batch_cost_us_ =
        std::max(frame_update_batch_cost_us_, left_before_us_ - left_after_us);
  }
  if (!held_an_update) {
    frame_batch_cost_us_ = std::max(frame_batch_cost_us_, left_before_us_ - left_after_us);
  }
  cost_measured_ = cost_measured_ || !held_an_update;
  if (left_at_first_no_us_ >= 0) {
    frame_batch_tail_us_ = std::max(frame_batch_tail_us_, left_at_first_no_us_ - left_at_end_us);
  }
}

bool StitchedFrameTime::another_batch_fits(int batches_run) const {
  if (!*may_continue_) return true;
  if (!shares_) return (*may_continue_)();
  const std::lock_guard lock(clock_mutex_);
  return (*time_left_us_)() > (batches_run < due_batches_ ? 0 : least_batch_us() * exchanges_) +
                                  after_steps_us_ + later_parts_us_;
}

bool StitchedFrameTime::update_batch_fits() const {
  return !shares_ || update_batch_cost_us_ <= 0 ||
         (*time_left_us_)() > update_batch_cost_us_ + after_steps_us_ + later_parts_us_;
}

void StitchedFrameTime::end_steps() {
  if (!shares_) return;
  if (cost_measured_) batch_cost_us_ = frame_batch_cost_us_;
  if (frame_update_batch_cost_us_ >= 0) update_batch_cost_us_ = frame_update_batch_cost_us_;
  // Kept from the last frame where a batch was told no (one with time to spare says nothing).
  if (frame_batch_tail_us_ >= 0) batch_tail_us_ = frame_batch_tail_us_;
  left_after_steps_us_ = (*time_left_us_)();
}

void StitchedFrameTime::end_frame() {
  if (!shares_) return;
  // It grows with the sub-volumes stepped (the large case's PCG FEM: 0.65-0.75 ms after six,
  // 1.0-1.2 after eight): it rises at once and falls a quarter of the way a frame, so that a
  // frame planned on a lighter one's measure does not run late by the difference.
  const std::int64_t after_us =
      std::max<std::int64_t>(left_after_steps_us_ - (*time_left_us_)(), 0);
  after_steps_us_ =
      after_us >= after_steps_us_ ? after_us : after_steps_us_ - (after_steps_us_ - after_us) / 4;
}

}  // namespace ultrasim::sim
