#pragma once

// A stitched frame's time (internal to StitchedVolume::step_sharing): the time left shared
// evenly over the frame's exchanges and, within each, over its batches; the budget a batch's
// sub-volumes ask; and what the batches cost, kept for the next frame's plan. Times in µs
// from the caller's clock (the library reads none).

#include <cstdint>
#include <functional>
#include <mutex>

#include "ultrasim/sim/engine.hpp"

namespace ultrasim::sim {

class StitchedFrameTime {
 public:
  using TimeLeftUs = std::function<std::int64_t()>;

  // `clock_mutex`: the frame's budget is one clock, asked in turn by the sub-volumes stepping in
  // parallel; it must outlive this.
  explicit StitchedFrameTime(std::mutex& clock_mutex);
  StitchedFrameTime(const StitchedFrameTime&) = delete;
  StitchedFrameTime& operator=(const StitchedFrameTime&) = delete;

  // A frame of up to `parts` exchanges starts; its time is shared only when both the budget and
  // the time left are given (they must outlive the frame). Sharing, it runs as many of them as
  // its touched batches' least work fits in (exchanges(): a divisor of `parts`, 1 at least),
  // and plans the first exchange's batches: the touched ones and as many of the others as fit at
  // the least batch work last measured (at least one: a frame with nothing touched still shares
  // its time among those that run).
  void start_frame(const StepBudget& may_continue, const TimeLeftUs& time_left_us, int parts,
                   int touched_batches, int other_batches);
  bool shares() const { return shares_; }
  int exchanges() const { return exchanges_; }
  int due_batches() const { return due_batches_; }

  // What the first exchange's batch `b` keeps back from the time left: the later batches' shares,
  // the later exchanges' parts and the work after the steps.
  std::int64_t first_part_reserve_us(int b) const;
  // The later exchange `part` (1 ≤ part < exchanges()) starts: its part is what is left over the
  // parts to go. What its batch j of `batches` keeps back.
  void start_later_part(int part);
  std::int64_t later_part_reserve_us(int part, int j, int batches) const;

  // Before a batch, with what it keeps back from the time left: whether its corotational
  // sub-volumes hold their due updates (its share covers no more than a batch with an update
  // took).
  bool begin_batch(std::int64_t reserve_us);
  // What the batch's sub-volumes ask while it steps (shared frames).
  const StepBudget& batch_budget() const { return batch_budget_; }
  // After the batch: whether one of its sub-volumes held its update, or brought its warped
  // system up to date. Measures the batch's least cost (up to its first question) and its tail
  // (after its first "no").
  void end_batch(bool held_an_update, bool updated);

  // Whether another batch of the first exchange may start, `batches_run` having run: a planned
  // one while time is left, a further one only if its least work in every exchange still ends in
  // time (the later exchanges step it too).
  bool another_batch_fits(int batches_run) const;
  // Whether a batch with a corotational update still ends in time (true until one was
  // measured).
  bool update_batch_fits() const;

  // The frame's steps are done: keeps their measures for the next frame's plan.
  void end_steps();
  // The frame's work after the steps is done: kept back from the next frame's time (where it
  // took less than the last, a quarter of the difference less).
  void end_frame();

 private:
  bool ask();  // batch_budget_'s
  // A batch's least work as last measured: up to its first question, then what it went on with
  // after a "no".
  std::int64_t least_batch_us() const { return batch_cost_us_ + batch_tail_us_; }
  // The most of `parts` exchanges (a divisor of it, 1 at least) in which `touched_batches`
  // batches a part at their least work last measured end within `left_us`.
  int exchanges_that_fit(std::int64_t left_us, int parts, int touched_batches) const;

  std::mutex& clock_mutex_;
  StepBudget batch_budget_;  // [this]: no allocation

  // Measured in earlier frames. The work after the steps (the last frame's, or falling toward
  // it from a longer one's). The costliest batch at its least (up
  // to its first question). The costliest up to its first question among those in which a
  // corotational sub-volume brought its warped system up to date (0 until one did). The longest
  // a batch worked on after its first "no", in the last frame that said one.
  std::int64_t after_steps_us_ = 0;
  std::int64_t batch_cost_us_ = 0;
  std::int64_t update_batch_cost_us_ = 0;
  std::int64_t batch_tail_us_ = 0;

  // This frame's.
  const StepBudget* may_continue_ = nullptr;
  const TimeLeftUs* time_left_us_ = nullptr;
  bool shares_ = false;
  int exchanges_ = 1;
  int due_batches_ = 1;
  std::int64_t left_at_start_us_ = 0;  // the first exchange's part
  std::int64_t later_parts_us_ = 0;    // kept back for the later exchanges
  std::int64_t part_us_ = 0;           // the later exchange's part
  std::int64_t left_after_steps_us_ = 0;
  // Measured over this frame's batches (-1: none).
  std::int64_t frame_batch_cost_us_ = 0;
  std::int64_t frame_update_batch_cost_us_ = -1;
  bool cost_measured_ = false;  // by a batch that held no update
  std::int64_t frame_batch_tail_us_ = -1;
  // The batch stepping now.
  std::int64_t reserve_us_ = 0;
  std::int64_t left_before_us_ = 0;
  std::int64_t left_at_first_question_us_ = -1;  // -1 until its first question
  std::int64_t left_at_first_no_us_ = -1;        // -1 until its first "no"
};

}  // namespace ultrasim::sim
