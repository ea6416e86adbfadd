// PieceBudget on a manual clock: work that goes on past its first "no" (the implicit MSDS's
// second step after its first step's CG was stopped) ends by its deadline from the frame after
// the first, and work that stops where it is told keeps the whole deadline.

#include "ultrasim/sched/piece_budget.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace ultrasim::sched {
namespace {

constexpr std::int64_t kDeadlineUs = 4000;
constexpr std::int64_t kFixedUs = 1200;     // a step's work before its first question
constexpr std::int64_t kIterationUs = 300;  // one CG iteration
constexpr std::int64_t kFinishUs = 100;     // a step's work after its last iteration

struct Frame {
  std::int64_t took_us = 0;
  int iterations = 0;  // over all steps
};

// `steps` steps, each: its fixed work, one iteration always, then iterations while the budget
// says yes (at most `max_iterations` a step), then its finish. As MsdsEngine's implicit step.
Frame run_steps(hal::ManualClock& clock, PieceBudget& budget, int steps, int max_iterations = 50,
                PieceBudget::Memory memory = PieceBudget::Memory::kTailAndPiece,
                std::int64_t share_us = kDeadlineUs) {
  const hal::TimestampUs start = clock.now_us();
  budget.start(start, start + share_us, memory);
  Frame frame;
  for (int s = 0; s < steps; ++s) {
    clock.advance_us(kFixedUs);
    for (int i = 0; i < max_iterations; ++i) {
      if (i > 0 && !budget.may_start_another()) break;
      clock.advance_us(kIterationUs);
      ++frame.iterations;
    }
    clock.advance_us(kFinishUs);
  }
  budget.finish();
  frame.took_us = clock.now_us() - start;
  return frame;
}

TEST(PieceBudget, WorkThatGoesOnPastItsFirstNoEndsByTheDeadlineFromTheNextFrame) {
  hal::ManualClock clock(1'000'000);
  PieceBudget budget(clock);
  // The first frame has no tail to keep back: its first step's iterations take the time and the
  // second step runs past the deadline (fixed + one iteration + finish).
  const Frame first = run_steps(clock, budget, 2);
  EXPECT_GT(first.took_us, kDeadlineUs);
  EXPECT_EQ(budget.tail_us(), kFinishUs + kFixedUs + kIterationUs + kFinishUs);
  for (int f = 0; f < 20; ++f) {
    const Frame frame = run_steps(clock, budget, 2);
    EXPECT_LE(frame.took_us, kDeadlineUs) << "frame " << f + 2;
    // Not at the cost of the work: the time left over is less than one more iteration.
    EXPECT_GT(frame.took_us + kIterationUs, kDeadlineUs) << "frame " << f + 2;
    EXPECT_GE(frame.iterations, 2);
  }
}

TEST(PieceBudget, WithoutTheTailKeptBackEveryFrameIsLate) {
  // What the stitched volume asks for (it keeps its batches' tails back itself), and what the
  // kiosk's simulation did before: the second step past the deadline every frame.
  hal::ManualClock clock;
  PieceBudget budget(clock);
  for (int f = 0; f < 5; ++f) {
    EXPECT_GT(run_steps(clock, budget, 2, 50, PieceBudget::Memory::kNothing).took_us, kDeadlineUs);
  }
  EXPECT_EQ(budget.tail_us(), 0);
}

TEST(PieceBudget, WorkThatStopsWhereItIsToldKeepsTheWholeDeadline) {
  // One step: after its "no" only its finish runs, so the tail is that and no more.
  hal::ManualClock clock;
  PieceBudget budget(clock);
  for (int f = 0; f < 5; ++f) {
    const Frame frame = run_steps(clock, budget, 1);
    EXPECT_LE(frame.took_us, kDeadlineUs + kFinishUs);
    EXPECT_EQ(frame.iterations, (kDeadlineUs - kFixedUs - kFinishUs) / kIterationUs) << f;
  }
  EXPECT_EQ(budget.tail_us(), kFinishUs);
}

TEST(PieceBudget, WorkToldNothingKeepsTheLastTailAndForgettingClearsTheMeasures) {
  hal::ManualClock clock;
  PieceBudget budget(clock);
  run_steps(clock, budget, 2);
  const std::int64_t tail = budget.tail_us();
  ASSERT_GT(tail, 0);
  // Converged early (two iterations fit easily): no "no", the tail stays for the frames that
  // will need it.
  const Frame quick = run_steps(clock, budget, 1, /*max_iterations=*/2);
  EXPECT_LT(quick.took_us, kDeadlineUs);
  EXPECT_EQ(budget.tail_us(), tail);
  budget.forget_measures();
  EXPECT_EQ(budget.tail_us(), 0);
  // The first question is measured from the start again: 1500 + 1500 ≥ 2000.
  budget.start(clock.now_us(), clock.now_us() + 2000);
  clock.advance_us(kFixedUs + kIterationUs);
  EXPECT_FALSE(budget.may_start_another());
}

TEST(PieceBudget, TheFirstQuestionTakesThePieceLastMeasuredNotTheWorkBeforeIt) {
  hal::ManualClock clock;
  PieceBudget budget(clock);
  run_steps(clock, budget, 1);  // measures a piece: one iteration
  // 1500 in, 2000 to go: one more iteration fits; the 1500 of fixed work before the question is
  // not a piece.
  budget.start(clock.now_us(), clock.now_us() + 2000);
  clock.advance_us(kFixedUs + kIterationUs);
  EXPECT_TRUE(budget.may_start_another());
}

TEST(PieceBudget, WorkToldNoAtItsFirstQuestionLearnsItsPieceOnceOneFits) {
  // 2500 µs: the first question comes after 1500 (fixed work and one iteration), and taken as a
  // piece that does not fit again. Half of it does, and then the iterations are measured.
  constexpr std::int64_t kShareUs = 2500;
  hal::ManualClock clock;
  PieceBudget budget(clock);
  const auto kMemory = PieceBudget::Memory::kTailAndPiece;
  EXPECT_EQ(run_steps(clock, budget, 1, 50, kMemory, kShareUs).iterations, 1);
  for (int f = 0; f < 5; ++f) {
    const Frame frame = run_steps(clock, budget, 1, 50, kMemory, kShareUs);
    EXPECT_EQ(frame.iterations, (kShareUs - kFixedUs - kFinishUs) / kIterationUs) << f;
    EXPECT_LE(frame.took_us, kShareUs) << f;
  }
}

TEST(PieceBudget, APieceAsLongAsTheLastMustEndByTheDeadline) {
  hal::ManualClock clock(500);
  PieceBudget budget(clock);
  budget.start(500, 500 + 1000);
  clock.advance_us(400);
  EXPECT_TRUE(budget.may_start_another());  // 900 + 400 < 1500
  EXPECT_EQ(budget.time_left_us(), 600);
  clock.advance_us(300);
  EXPECT_TRUE(budget.may_start_another());  // 1200 + 300 = 1500: ends on the deadline
  clock.advance_us(301);
  EXPECT_FALSE(budget.may_start_another());  // 1501 + 301 > 1500
  clock.advance_us(50);
  budget.finish();
  EXPECT_EQ(budget.tail_us(), 50);
}

}  // namespace
}  // namespace ultrasim::sched
