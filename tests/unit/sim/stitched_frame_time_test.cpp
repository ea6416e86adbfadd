// StitchedFrameTime on a manual clock: the exchanges the touched batches fit at their least
// work, the first exchange's batches planned at the cost last measured, each batch's reserve, the
// budget's "no" once a batch's share is spent and its tail kept back the next frame, the
// corotational updates held where a share covers no more than a batch with an update took, and no
// sharing without the time left.

#include "../../../app/sim/src/stitched_frame_time.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <mutex>

namespace ultrasim::sim {
namespace {

const StepBudget kAlways = [] { return true; };

// A frame time on a manual clock: the time left is what the test sets.
class StitchedFrameTimeTest : public ::testing::Test {
 protected:
  // A frame starting with `left_us` left.
  void start_frame(std::int64_t left_us, int parts, int touched_batches, int other_batches,
                   const StepBudget& may_continue = kAlways) {
    left_us_ = left_us;
    time_.start_frame(may_continue, time_left_us_, parts, touched_batches, other_batches);
  }
  // One batch: `fixed_us` of work before its first question, then `after_us` to its end.
  void run_batch(std::int64_t reserve_us, std::int64_t fixed_us, std::int64_t after_us,
                 bool updated = false) {
    time_.begin_batch(reserve_us);
    left_us_ -= fixed_us;
    time_.batch_budget()();
    left_us_ -= after_us;
    time_.end_batch(false, updated);
  }

  // The frame's steps end, and the work after them takes `after_us`.
  void end_frame(std::int64_t after_us) {
    time_.end_steps();
    left_us_ -= after_us;
    time_.end_frame();
  }

  std::mutex mutex_;
  StitchedFrameTime time_{mutex_};
  std::int64_t left_us_ = 0;
  const StitchedFrameTime::TimeLeftUs time_left_us_ = [this] { return left_us_; };
};

TEST_F(StitchedFrameTimeTest, PlansTheBatchesThatFitAtTheCostLastMeasured) {
  // The first frame knows no batch's cost: the touched batch alone is planned.
  start_frame(6000, 1, 1, 5);
  ASSERT_TRUE(time_.shares());
  EXPECT_EQ(time_.due_batches(), 1);
  EXPECT_EQ(time_.first_part_reserve_us(0), 0);
  run_batch(time_.first_part_reserve_us(0), 300, 700);  // costs 300 at its least
  time_.end_steps();
  left_us_ -= 400;  // the work after the steps
  time_.end_frame();

  // Two exchanges: the first plans on its half of what is left less the work after the steps,
  // (6000 − 400) / 2 = 2800 µs, nine batches at 300: the touched one and all five others.
  start_frame(6000, 2, 1, 5);
  EXPECT_EQ(time_.due_batches(), 6);
  // Each keeps back the work after the steps, the later exchange's part and the later batches'
  // shares: 400 + 2800 + 2800 × 5 / 6.
  EXPECT_EQ(time_.first_part_reserve_us(0), 400 + 2800 + 2333);
  EXPECT_EQ(time_.first_part_reserve_us(5), 400 + 2800);
  // A planned batch while time is left beyond what is kept back; a further one only if its
  // least work (300) in both exchanges (the later one steps it too) still ends in time.
  left_us_ = 3400;
  EXPECT_TRUE(time_.another_batch_fits(2));
  EXPECT_FALSE(time_.another_batch_fits(6));
  left_us_ = 3800;
  EXPECT_FALSE(time_.another_batch_fits(6));
  left_us_ = 3801;
  EXPECT_TRUE(time_.another_batch_fits(6));
  // The later exchange's part: what is left less the work after the steps, over the parts to go;
  // its first batch of two keeps back the second's half.
  left_us_ = 2400;
  time_.start_later_part(1);
  EXPECT_EQ(time_.later_part_reserve_us(1, 0, 2), 400 + 1000);
  EXPECT_EQ(time_.later_part_reserve_us(1, 1, 2), 400);
}

TEST_F(StitchedFrameTimeTest, RunsTheExchangesItsTouchedBatchesFitAtTheirLeastWork) {
  start_frame(6000, 2, 1, 0);
  EXPECT_EQ(time_.exchanges(), 2) << "no batch measured yet";
  // A batch told no at its first question, 300 µs in, that went on 200 µs: its least work is 500.
  run_batch(5700, 300, 200);
  end_frame(400);  // the work after the steps

  // Three touched batches in two exchanges at 500 each, and the 400 after them: 3400 µs.
  start_frame(3400, 2, 3, 4);
  EXPECT_EQ(time_.exchanges(), 2);
  EXPECT_EQ(time_.due_batches(), 3) << "(3400 - 400) / 2 = 1500 µs an exchange: three at 500";
  EXPECT_EQ(time_.first_part_reserve_us(0), 400 + 1500 + 1000);
  end_frame(400);
  // A microsecond less: one exchange, planned on the whole 2999 µs (five batches at 500).
  start_frame(3399, 2, 3, 4);
  EXPECT_EQ(time_.exchanges(), 1);
  EXPECT_EQ(time_.due_batches(), 5);
  EXPECT_EQ(time_.first_part_reserve_us(4), 400);
  end_frame(400);
  // Of four, the most that divide them and fit: two; one at least, whatever the time.
  start_frame(3400, 4, 3, 0);
  EXPECT_EQ(time_.exchanges(), 2);
  end_frame(400);
  start_frame(100, 4, 3, 0);
  EXPECT_EQ(time_.exchanges(), 1);
  end_frame(400);
  // Nothing touched: every exchange.
  start_frame(500, 4, 0, 3);
  EXPECT_EQ(time_.exchanges(), 4);
}

// The work after the steps grows with the sub-volumes stepped: a longer one is kept back at once,
// a shorter one only a quarter of the way a frame (a frame planned on a lighter frame's measure
// ran late by the difference).
TEST_F(StitchedFrameTimeTest, KeepsBackTheWorkAfterTheStepsRisingAtOnceFallingSlowly) {
  const auto kept_back = [this] {
    start_frame(6000, 1, 1, 0);
    return time_.first_part_reserve_us(0);  // the last batch: the work after the steps alone
  };
  EXPECT_EQ(kept_back(), 0);
  end_frame(400);
  EXPECT_EQ(kept_back(), 400);
  end_frame(800);
  EXPECT_EQ(kept_back(), 800);
  end_frame(400);
  EXPECT_EQ(kept_back(), 700);
  end_frame(400);
  EXPECT_EQ(kept_back(), 625);
  end_frame(900);
  EXPECT_EQ(kept_back(), 900);
}

TEST_F(StitchedFrameTimeTest, ABatchHearsNoPastItsShareAndKeepsItsTailBackTheNextFrame) {
  start_frame(6000, 1, 1, 0);
  time_.begin_batch(1000);
  left_us_ = 3000;
  EXPECT_TRUE(time_.batch_budget()());
  left_us_ = 900;
  EXPECT_FALSE(time_.batch_budget()()) << "900 µs left, 1000 kept back";
  left_us_ = 600;  // it went on 300 µs after its "no"
  time_.end_batch(false, false);
  time_.end_steps();
  time_.end_frame();

  start_frame(6000, 1, 1, 0);
  time_.begin_batch(1000);
  left_us_ = 1301;
  EXPECT_TRUE(time_.batch_budget()());
  left_us_ = 1300;
  EXPECT_FALSE(time_.batch_budget()()) << "the last frame's 300 µs tail kept back too";
  // The frame's own budget says no whatever the time.
  const StepBudget never = [] { return false; };
  start_frame(6000, 1, 1, 0, never);
  time_.begin_batch(0);
  EXPECT_FALSE(time_.batch_budget()());
}

TEST_F(StitchedFrameTimeTest, HoldsUpdatesWhereTheShareCoversNoMoreThanABatchWithAnUpdateTook) {
  start_frame(16000, 1, 2, 0);
  EXPECT_TRUE(time_.update_batch_fits()) << "no batch with an update measured yet";
  EXPECT_FALSE(time_.begin_batch(0)) << "no cost measured yet";
  left_us_ -= 2000;  // a batch that brought its warped system up to date
  time_.batch_budget()();
  time_.end_batch(false, true);
  run_batch(0, 300, 100);
  time_.end_steps();
  time_.end_frame();  // nothing after the steps

  start_frame(6000, 1, 2, 0);
  EXPECT_TRUE(time_.begin_batch(4000)) << "a 2000 µs share: no more than the update took";
  time_.end_batch(false, false);
  EXPECT_FALSE(time_.begin_batch(3999));
  time_.end_batch(false, false);
  left_us_ = 2000;
  EXPECT_FALSE(time_.update_batch_fits());
  left_us_ = 2001;
  EXPECT_TRUE(time_.update_batch_fits());
}

TEST_F(StitchedFrameTimeTest, WithoutTheTimeLeftNothingIsShared) {
  const StitchedFrameTime::TimeLeftUs none;
  bool more = true;
  const StepBudget budget = [&more] { return more; };
  time_.start_frame(budget, none, 2, 3, 4);
  EXPECT_FALSE(time_.shares());
  EXPECT_FALSE(time_.begin_batch(0));
  time_.end_batch(false, false);
  EXPECT_TRUE(time_.update_batch_fits());
  EXPECT_TRUE(time_.another_batch_fits(100));
  more = false;
  EXPECT_FALSE(time_.another_batch_fits(0)) << "the frame's own budget";
  const StepBudget unlimited;
  time_.start_frame(unlimited, none, 1, 1, 1);
  EXPECT_TRUE(time_.another_batch_fits(100));
  time_.end_steps();
  time_.end_frame();
}

}  // namespace
}  // namespace ultrasim::sim
