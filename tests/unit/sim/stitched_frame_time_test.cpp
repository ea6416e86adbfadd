// StitchedFrameTime on a manual clock: the first exchange's batches planned at the cost last
// measured, each batch's reserve, the budget's "no" once a batch's share is spent and its tail
// kept back the next frame, the corotational updates held where a share covers no more than a
// batch with an update took, and no sharing without the time left.

#include "../../../app/sim/src/stitched_frame_time.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <mutex>

namespace ultrasim::sim {
namespace {

struct ManualClock {
  std::int64_t left_us = 0;
  StitchedFrameTime::TimeLeftUs time_left_us = [this] { return left_us; };
};

const StepBudget kAlways = [] { return true; };

// One batch: `fixed_us` of work before its first question, then `after_us` to its end.
void run_batch(StitchedFrameTime& time, ManualClock& clock, std::int64_t reserve_us,
               std::int64_t fixed_us, std::int64_t after_us, bool updated = false) {
  time.begin_batch(reserve_us);
  clock.left_us -= fixed_us;
  time.batch_budget()();
  clock.left_us -= after_us;
  time.end_batch(false, updated);
}

TEST(StitchedFrameTime, PlansTheBatchesThatFitAtTheCostLastMeasured) {
  std::mutex mutex;
  StitchedFrameTime time(mutex);
  ManualClock clock;
  // The first frame knows no batch's cost: the touched batch alone is planned.
  clock.left_us = 6000;
  time.start_frame(kAlways, clock.time_left_us, 1, 1, 5);
  ASSERT_TRUE(time.shares());
  EXPECT_EQ(time.due_batches(), 1);
  EXPECT_EQ(time.first_part_reserve_us(0), 0);
  run_batch(time, clock, time.first_part_reserve_us(0), 300, 700);  // costs 300 at its least
  time.end_steps();
  clock.left_us -= 400;  // the work after the steps
  time.end_frame();

  // Two exchanges: the first plans on its half of what is left less the work after the steps,
  // (6000 − 400) / 2 = 2800 µs, nine batches at 300: the touched one and all five others.
  clock.left_us = 6000;
  time.start_frame(kAlways, clock.time_left_us, 2, 1, 5);
  EXPECT_EQ(time.due_batches(), 6);
  // Each keeps back the work after the steps, the later exchange's part and the later batches'
  // shares: 400 + 2800 + 2800 × 5 / 6.
  EXPECT_EQ(time.first_part_reserve_us(0), 400 + 2800 + 2333);
  EXPECT_EQ(time.first_part_reserve_us(5), 400 + 2800);
  // A planned batch while time is left beyond what is kept back; a further one only if one at
  // its least cost (300) still ends in time.
  clock.left_us = 3400;
  EXPECT_TRUE(time.another_batch_fits(2));
  EXPECT_FALSE(time.another_batch_fits(6));
  clock.left_us = 3501;
  EXPECT_TRUE(time.another_batch_fits(6));
  // The later exchange's part: what is left less the work after the steps, over the parts to go;
  // its first batch of two keeps back the second's half.
  clock.left_us = 2400;
  time.start_later_part(1);
  EXPECT_EQ(time.later_part_reserve_us(1, 0, 2), 400 + 1000);
  EXPECT_EQ(time.later_part_reserve_us(1, 1, 2), 400);
}

TEST(StitchedFrameTime, ABatchHearsNoPastItsShareAndKeepsItsTailBackTheNextFrame) {
  std::mutex mutex;
  StitchedFrameTime time(mutex);
  ManualClock clock;
  clock.left_us = 6000;
  time.start_frame(kAlways, clock.time_left_us, 1, 1, 0);
  time.begin_batch(1000);
  clock.left_us = 3000;
  EXPECT_TRUE(time.batch_budget()());
  clock.left_us = 900;
  EXPECT_FALSE(time.batch_budget()()) << "900 µs left, 1000 kept back";
  clock.left_us = 600;  // it went on 300 µs after its "no"
  time.end_batch(false, false);
  time.end_steps();
  time.end_frame();

  clock.left_us = 6000;
  time.start_frame(kAlways, clock.time_left_us, 1, 1, 0);
  time.begin_batch(1000);
  clock.left_us = 1301;
  EXPECT_TRUE(time.batch_budget()());
  clock.left_us = 1300;
  EXPECT_FALSE(time.batch_budget()()) << "the last frame's 300 µs tail kept back too";
  // The frame's own budget says no whatever the time.
  const StepBudget never = [] { return false; };
  clock.left_us = 6000;
  time.start_frame(never, clock.time_left_us, 1, 1, 0);
  time.begin_batch(0);
  EXPECT_FALSE(time.batch_budget()());
}

TEST(StitchedFrameTime, HoldsUpdatesWhereTheShareCoversNoMoreThanABatchWithAnUpdateTook) {
  std::mutex mutex;
  StitchedFrameTime time(mutex);
  ManualClock clock;
  clock.left_us = 16000;
  time.start_frame(kAlways, clock.time_left_us, 1, 2, 0);
  EXPECT_TRUE(time.update_batch_fits()) << "no batch with an update measured yet";
  EXPECT_FALSE(time.begin_batch(0)) << "no cost measured yet";
  clock.left_us -= 2000;  // a batch that brought its warped system up to date
  time.batch_budget()();
  time.end_batch(false, true);
  run_batch(time, clock, 0, 300, 100);
  time.end_steps();
  time.end_frame();  // nothing after the steps

  clock.left_us = 6000;
  time.start_frame(kAlways, clock.time_left_us, 1, 2, 0);
  EXPECT_TRUE(time.begin_batch(4000)) << "a 2000 µs share: no more than the update took";
  time.end_batch(false, false);
  EXPECT_FALSE(time.begin_batch(3999));
  time.end_batch(false, false);
  clock.left_us = 2000;
  EXPECT_FALSE(time.update_batch_fits());
  clock.left_us = 2001;
  EXPECT_TRUE(time.update_batch_fits());
}

TEST(StitchedFrameTime, WithoutTheTimeLeftNothingIsShared) {
  std::mutex mutex;
  StitchedFrameTime time(mutex);
  const StitchedFrameTime::TimeLeftUs none;
  bool more = true;
  const StepBudget budget = [&more] { return more; };
  time.start_frame(budget, none, 2, 3, 4);
  EXPECT_FALSE(time.shares());
  EXPECT_FALSE(time.begin_batch(0));
  time.end_batch(false, false);
  EXPECT_TRUE(time.update_batch_fits());
  EXPECT_TRUE(time.another_batch_fits(100));
  more = false;
  EXPECT_FALSE(time.another_batch_fits(0)) << "the frame's own budget";
  const StepBudget unlimited;
  time.start_frame(unlimited, none, 1, 1, 1);
  EXPECT_TRUE(time.another_batch_fits(100));
  time.end_steps();
  time.end_frame();
}

}  // namespace
}  // namespace ultrasim::sim
