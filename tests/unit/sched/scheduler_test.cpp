// The fixed-budget scheduler on a manual clock: each test task advances the clock by what it
// "costs", so every skip, slip, overrun and deadline miss is exact and deterministic.

#include "ultrasim/sched/scheduler.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "allocation_counter.hpp"

namespace ultrasim::sched {
namespace {

// A task that takes `cost_us` of manual-clock time and logs when it ran.
struct FakeTask {
  FakeTask(hal::ManualClock* c, std::int64_t cost, std::string task_name,
           std::vector<std::string>* run_log = nullptr)
      : clock(c), cost_us(cost), name(std::move(task_name)), order(run_log) {}

  hal::ManualClock* clock;
  std::int64_t cost_us;
  std::string name;
  std::vector<std::string>* order;  // shared run log, or null
  std::vector<TaskTick> ticks;      // what it was told, per run

  static void run(void* context, const TaskTick& tick) {
    auto* self = static_cast<FakeTask*>(context);
    self->ticks.push_back(tick);
    if (self->order != nullptr) self->order->push_back(self->name);
    self->clock->advance_us(self->cost_us);
  }
};

TaskSpec spec_for(FakeTask& task, double rate_hz, std::int64_t budget_us, int priority,
                  bool mandatory = false) {
  TaskSpec s;
  s.name = task.name;
  s.rate_hz = rate_hz;
  s.budget_us = budget_us;
  s.priority = priority;
  s.mandatory = mandatory;
  s.run = &FakeTask::run;
  s.context = &task;
  return s;
}

TEST(Scheduler, RunsDueTasksInPriorityOrderWithTiesInTableOrder) {
  hal::ManualClock clock;
  std::vector<std::string> order;
  FakeTask render{&clock, 100, "render", &order}, input{&clock, 100, "input", &order},
      solve{&clock, 100, "solve", &order}, bscan{&clock, 100, "bscan", &order};
  const std::vector<TaskSpec> table{spec_for(render, 0, 200, 50), spec_for(input, 0, 200, 0),
                                    spec_for(solve, 0, 200, 10), spec_for(bscan, 0, 200, 10)};
  Scheduler scheduler(clock, table);
  scheduler.tick();
  EXPECT_EQ(order, (std::vector<std::string>{"input", "solve", "bscan", "render"}));
  ASSERT_EQ(scheduler.task_stats().size(), 4u);
  EXPECT_EQ(scheduler.task_stats()[0].name, "input");
}

TEST(Scheduler, AMandatoryTaskKeepsBackWhatItsLastRunsTookAtMostItsBudget) {
  hal::ManualClock clock;
  // The rendering's budget is 9 ms but it takes 2 ms; the optional B-scan needs 10 ms of 16.
  FakeTask bscan{&clock, 1'000, "bscan"}, render{&clock, 2'000, "render"};
  TaskSpec render_spec = spec_for(render, 0, 9'000, 1, true);
  render_spec.expect_from_last_runs = 3;
  const std::vector<TaskSpec> table{spec_for(bscan, 0, 10'000, 0), render_spec};
  Scheduler scheduler(clock, table, {60.0, 16'000});
  const auto tick = [&] {
    const std::int64_t runs = scheduler.find("bscan")->runs;
    scheduler.tick();
    clock.advance_us(16'000);
    return scheduler.find("bscan")->runs > runs;
  };
  // Until the rendering has run three times its budget is kept back: 16 - 9 < 10.
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(tick()) << "tick " << i;
  // Then the longest of its last three runs, 2 ms: 16 - 2 >= 10.
  EXPECT_TRUE(tick());
  EXPECT_TRUE(tick());
  // One slow run (7 ms) is kept back for the next three ticks, then forgotten.
  render.cost_us = 7'000;
  EXPECT_TRUE(tick());  // decided before the slow run
  render.cost_us = 2'000;
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(tick()) << "after the slow run, tick " << i;
  EXPECT_TRUE(tick());
  // Never more than its budget: a run of 20 ms keeps back 9, and a 7 ms task fits beside it.
  render.cost_us = 20'000;
  FakeTask view{&clock, 1'000, "view"};
  TaskSpec slow_render = spec_for(render, 0, 9'000, 1, true);
  slow_render.expect_from_last_runs = 3;
  const std::vector<TaskSpec> slow_table{spec_for(view, 0, 7'000, 0), slow_render};
  Scheduler slow(clock, slow_table, {60.0, 16'000});
  for (int i = 0; i < 6; ++i) {
    slow.tick();
    clock.advance_us(16'000);
  }
  EXPECT_EQ(slow.find("view")->runs, 6);
  EXPECT_EQ(slow.find("view")->slips, 0);
}

TEST(Scheduler, AnOptionalTaskStartsOnlyWhereWhatItsLastRunsTookFits) {
  hal::ManualClock clock;
  // The B-scan's budget is 2 ms but it takes 5; then it takes 1 ms.
  FakeTask solve{&clock, 0, "solve"}, bscan{&clock, 5'000, "bscan"};
  TaskSpec bscan_spec = spec_for(bscan, 0, 2'000, 1);
  bscan_spec.expect_from_last_runs = 2;
  bscan_spec.max_consecutive_slips = 5;
  const std::vector<TaskSpec> table{spec_for(solve, 0, 10'000, 0, true), bscan_spec};
  Scheduler scheduler(clock, table, {60.0, 10'000});
  const auto tick_after_solve = [&](std::int64_t solve_us) {
    solve.cost_us = solve_us;
    const std::int64_t runs = scheduler.find("bscan")->runs;
    scheduler.tick();
    clock.advance_us(10'000);
    return scheduler.find("bscan")->runs > runs;
  };
  // Its budget until it has run twice: 3 ms left is enough.
  EXPECT_TRUE(tick_after_solve(7'000));
  EXPECT_TRUE(tick_after_solve(7'000));
  // Then 5 ms: 3 ms left is not, 5 ms is.
  EXPECT_FALSE(tick_after_solve(7'000));
  EXPECT_TRUE(tick_after_solve(5'000));
  // Quicker now (1 ms): once its last two runs were, 1.5 ms left is enough, below its budget.
  bscan.cost_us = 1'000;
  EXPECT_TRUE(tick_after_solve(5'000));
  EXPECT_TRUE(tick_after_solve(5'000));
  EXPECT_TRUE(tick_after_solve(8'500));
  EXPECT_EQ(scheduler.find("bscan")->slips, 1);
}

TEST(Scheduler, OneSlowRunInTenIsNotExpectedAgain) {
  hal::ManualClock clock;
  // The B-scan takes 1 ms, once 8 ms; 5 ms are left for it each tick.
  FakeTask solve{&clock, 11'000, "solve"}, bscan{&clock, 1'000, "bscan"};
  TaskSpec bscan_spec = spec_for(bscan, 0, 1'000, 1);
  bscan_spec.expect_from_last_runs = 10;
  bscan_spec.max_consecutive_slips = 1;
  const std::vector<TaskSpec> table{spec_for(solve, 0, 11'000, 0, true), bscan_spec};
  Scheduler scheduler(clock, table, {60.0, 16'000});
  for (int i = 0; i < 30; ++i) {
    bscan.cost_us = i == 12 ? 8'000 : 1'000;
    scheduler.tick();
    clock.advance_us(16'000);
  }
  // Every tick ran it: the 8 ms run is the slowest tenth of the last ten, not what is expected.
  EXPECT_EQ(scheduler.find("bscan")->runs, 30);
  EXPECT_EQ(scheduler.find("bscan")->slips, 0);
  // Two slow runs in the last ten are: then it waits (and is forced after one slip).
  bscan.cost_us = 8'000;
  for (int i = 0; i < 2; ++i) {
    scheduler.tick();
    clock.advance_us(16'000);
  }
  EXPECT_EQ(scheduler.find("bscan")->slips, 0);
  bscan.cost_us = 1'000;
  scheduler.tick();
  clock.advance_us(16'000);
  EXPECT_EQ(scheduler.find("bscan")->slips, 1);
}

TEST(Scheduler, RejectsAReserveOverMoreRunsThanItKeeps) {
  hal::ManualClock clock;
  FakeTask render{&clock, 10, "render"};
  for (const int runs : {-1, kMaxExpectedRuns + 1}) {
    TaskSpec spec = spec_for(render, 0, 100, 0, true);
    spec.expect_from_last_runs = runs;
    const std::vector<TaskSpec> table{spec};
    EXPECT_THROW(Scheduler(clock, table), std::invalid_argument) << runs;
  }
  // An optional task expected from its runs that is never forced could starve for good.
  TaskSpec optional = spec_for(render, 0, 100, 0);
  optional.expect_from_last_runs = 10;
  const std::vector<TaskSpec> never_forced{optional};
  EXPECT_THROW(Scheduler(clock, never_forced), std::invalid_argument);
  optional.max_consecutive_slips = 3;
  const std::vector<TaskSpec> forced{optional};
  EXPECT_NO_THROW(Scheduler(clock, forced));
}

TEST(Scheduler, TaskRatesDivideTheLoopRate) {
  hal::ManualClock clock;
  FakeTask every{&clock, 10, "every"}, half{&clock, 10, "half"}, tenth{&clock, 10, "tenth"},
      odd{&clock, 10, "odd"};
  const std::vector<TaskSpec> table{spec_for(every, 60, 100, 0), spec_for(half, 30, 100, 1),
                                    spec_for(tenth, 6, 100, 2), spec_for(odd, 25, 100, 3)};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  for (int i = 0; i < 60; ++i) {
    scheduler.tick();
    clock.advance_us(16'667);
  }
  EXPECT_EQ(scheduler.find("every")->runs, 60);
  EXPECT_EQ(scheduler.find("half")->runs, 30);
  EXPECT_EQ(scheduler.find("tenth")->runs, 6);
  EXPECT_EQ(scheduler.find("odd")->runs, 30);  // 60 / 25 rounds to every 2nd tick
  EXPECT_EQ(half.ticks[1].tick_index, 2);
  EXPECT_EQ(tenth.ticks[1].tick_index, 10);
}

TEST(Scheduler, ATaskThatDoesNotFitIsSkippedCountedAsASlipAndRunsWhenThereIsTime) {
  hal::ManualClock clock;
  FakeTask solve{&clock, 12'000, "solve"}, surfaces{&clock, 1'000, "surfaces"};
  const std::vector<TaskSpec> table{spec_for(solve, 0, 12'000, 0),
                                    spec_for(surfaces, 30, 6'000, 1)};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  // 16.7 ms − 12 ms leaves 4.7 ms: the 6 ms surfaces task does not fit.
  TickReport r = scheduler.tick();
  EXPECT_EQ(r.tasks_run, 1);
  EXPECT_EQ(r.tasks_skipped, 1);
  EXPECT_FALSE(r.deadline_missed);
  EXPECT_EQ(scheduler.find("surfaces")->slips, 1);
  EXPECT_EQ(scheduler.find("surfaces")->runs, 0);
  // Still due on the next tick: once the solve is cheap it runs, at once, not a period later.
  solve.cost_us = 2'000;
  r = scheduler.tick();
  EXPECT_EQ(r.tasks_run, 2);
  EXPECT_EQ(scheduler.find("surfaces")->runs, 1);
  EXPECT_EQ(surfaces.ticks.at(0).tick_index, 1);
  EXPECT_EQ(surfaces.ticks.at(0).time_left_us, 16'667 - 2'000);
}

TEST(Scheduler, AnOptionalTaskStarvedForItsSlipLimitRunsAnywayAndIsCounted) {
  hal::ManualClock clock;
  FakeTask solve{&clock, 12'000, "solve"}, bscan{&clock, 3'000, "bscan"};
  TaskSpec bscan_spec = spec_for(bscan, 0, 6'000, 1);
  bscan_spec.max_consecutive_slips = 2;
  const std::vector<TaskSpec> table{spec_for(solve, 0, 12'000, 0, true), bscan_spec};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  // Never enough time: skipped twice, forced on the third tick, then the count starts again.
  std::vector<int> ran;
  for (int t = 0; t < 6; ++t) ran.push_back(scheduler.tick().tasks_run);
  EXPECT_EQ(ran, (std::vector<int>{1, 1, 2, 1, 1, 2}));
  const TaskStats& s = *scheduler.find("bscan");
  EXPECT_EQ(s.slips, 4);
  EXPECT_EQ(s.runs, 2);
  EXPECT_EQ(s.forced_runs, 2);
  // A run with time to spare resets the count without being forced.
  solve.cost_us = 1'000;
  scheduler.tick();
  EXPECT_EQ(scheduler.find("bscan")->forced_runs, 2);
  EXPECT_EQ(scheduler.find("bscan")->runs, 3);
}

// Each task's latest run (its tick and time): what the report shows of a slow frame's parts. A
// skipped task keeps its last run's, so a frame that skipped it is told by the tick.
TEST(Scheduler, RemembersEachTasksLatestRunAndItsTick) {
  hal::ManualClock clock;
  FakeTask solve{&clock, 2'000, "solve"}, bscan{&clock, 3'000, "bscan"};
  const std::vector<TaskSpec> table{spec_for(solve, 0, 12'000, 0, true),
                                    spec_for(bscan, 0, 6'000, 1)};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  EXPECT_EQ(scheduler.find("bscan")->last_run_tick, -1);
  scheduler.tick();
  EXPECT_EQ(scheduler.find("solve")->last_run_tick, 0);
  EXPECT_EQ(scheduler.find("solve")->last_run_us, 2'000);
  EXPECT_EQ(scheduler.find("bscan")->last_run_tick, 0);
  EXPECT_EQ(scheduler.find("bscan")->last_run_us, 3'000);
  solve.cost_us = 15'000;  // no time left for the B-scan
  scheduler.tick();
  EXPECT_EQ(scheduler.find("solve")->last_run_tick, 1);
  EXPECT_EQ(scheduler.find("solve")->last_run_us, 15'000);
  EXPECT_EQ(scheduler.find("bscan")->last_run_tick, 0);
  EXPECT_EQ(scheduler.find("bscan")->last_run_us, 3'000);
}

TEST(Scheduler, MandatoryTasksRunEvenWhenTheBudgetIsSpentAndTheMissIsCounted) {
  hal::ManualClock clock;
  FakeTask solve{&clock, 20'000, "solve"}, render{&clock, 3'000, "render"},
      optional{&clock, 10, "optional"};
  const std::vector<TaskSpec> table{spec_for(solve, 0, 12'000, 0),
                                    spec_for(render, 0, 4'000, 1, /*mandatory=*/true),
                                    spec_for(optional, 0, 100, 2)};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  const TickReport r = scheduler.tick();
  EXPECT_EQ(scheduler.find("render")->runs, 1);
  EXPECT_EQ(render.ticks.at(0).time_left_us, 16'667 - 20'000);
  EXPECT_EQ(scheduler.find("optional")->slips, 1);
  EXPECT_EQ(r.duration_us, 23'000);
  EXPECT_TRUE(r.deadline_missed);
  EXPECT_EQ(scheduler.frame_stats().deadline_misses(), 1);
  EXPECT_EQ(solve.ticks.at(0).time_left_us, 16'667 - 4'000);  // the render's time is reserved
  EXPECT_EQ(scheduler.find("solve")->overruns, 1);            // 20 ms against its 12 ms budget
  EXPECT_EQ(scheduler.find("render")->overruns, 0);
}

TEST(Scheduler, TheBudgetOfAMandatoryTaskStillToComeIsKeptForIt) {
  hal::ManualClock clock;
  FakeTask bscan{&clock, 3'000, "bscan"}, render{&clock, 6'000, "render"};
  const std::vector<TaskSpec> table{spec_for(bscan, 0, 4'000, 1),
                                    spec_for(render, 30, 7'000, 2, /*mandatory=*/true)};
  Scheduler scheduler(clock, table, {60.0, 10'000});
  // Tick 0: the render is due and keeps 7 ms of the 10; the 4 ms B-scan does not fit in 3.
  scheduler.tick();
  EXPECT_EQ(scheduler.find("bscan")->slips, 1);
  EXPECT_EQ(scheduler.find("render")->runs, 1);
  // Tick 1: the 30 Hz render is not due: the B-scan has the whole frame.
  scheduler.tick();
  EXPECT_EQ(scheduler.find("bscan")->runs, 1);
  EXPECT_EQ(bscan.ticks.at(0).time_left_us, 10'000);
  EXPECT_EQ(scheduler.frame_stats().deadline_misses(), 0);
}

TEST(Scheduler, PerTaskTimesAndFrameTimesAreAccounted) {
  hal::ManualClock clock;
  FakeTask a{&clock, 1'000, "a"}, b{&clock, 0, "b"};
  const std::vector<TaskSpec> table{spec_for(a, 0, 1'500, 0), spec_for(b, 0, 5'000, 1)};
  Scheduler scheduler(clock, table, {60.0, 16'667});
  const std::int64_t b_costs[] = {2'000, 4'000, 6'000, 3'000};
  for (std::int64_t cost : b_costs) {
    b.cost_us = cost;
    scheduler.tick();
  }
  const TaskStats& sb = *scheduler.find("b");
  EXPECT_EQ(sb.runs, 4);
  EXPECT_EQ(sb.time.min_us(), 2'000);
  EXPECT_EQ(sb.time.max_us(), 6'000);
  EXPECT_DOUBLE_EQ(sb.time.mean_us(), 3'750.0);
  EXPECT_EQ(sb.overruns, 1);
  EXPECT_EQ(scheduler.frame_stats().count(), 4);
  EXPECT_EQ(scheduler.frame_stats().max_us(), 7'000);
  EXPECT_EQ(scheduler.frame_stats().deadline_misses(), 0);
  EXPECT_EQ(scheduler.tick_count(), 4);
  EXPECT_EQ(scheduler.find("missing"), nullptr);
}

TEST(Scheduler, AnAnytimeTaskIsToldTheTimeLeftInTheFrame) {
  hal::ManualClock clock;
  FakeTask input{&clock, 700, "input"}, solves{&clock, 0, "solves"};
  const std::vector<TaskSpec> table{spec_for(input, 0, 1'000, 0), spec_for(solves, 0, 500, 1)};
  Scheduler scheduler(clock, table, {60.0, 10'000});
  clock.advance_us(123);  // the tick starts at an arbitrary time
  scheduler.tick();
  ASSERT_EQ(solves.ticks.size(), 1u);
  EXPECT_EQ(solves.ticks[0].tick_start_us, 123);
  EXPECT_EQ(solves.ticks[0].time_left_us, 10'000 - 700);
}

TEST(Scheduler, ABadTableIsRefusedNamingTheTask) {
  hal::ManualClock clock;
  FakeTask t{&clock, 0, "solve"};
  const auto refused = [&](TaskSpec spec, const std::string& words) {
    try {
      Scheduler(clock, std::vector<TaskSpec>{spec});
      ADD_FAILURE() << "expected std::invalid_argument for " << words;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("solve"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  TaskSpec no_run = spec_for(t, 0, 100, 0);
  no_run.run = nullptr;
  refused(no_run, "run function");
  refused(spec_for(t, 0, 0, 0), "budget_us");
  refused(spec_for(t, -1, 100, 0), "rate_hz");
  EXPECT_THROW(Scheduler(clock, std::vector<TaskSpec>{}, {0.0, 100}), std::invalid_argument);
  EXPECT_THROW(Scheduler(clock, std::vector<TaskSpec>{}, {60.0, 0}), std::invalid_argument);
}

void nothing(void*, const TaskTick&) {}

TEST(Scheduler, ATickDoesNotAllocate) {
  hal::ManualClock clock;
  std::vector<TaskSpec> table;
  for (int i = 0; i < 8; ++i) {
    TaskSpec s;
    s.name = "task";
    s.rate_hz = 60.0 / (i + 1);
    s.budget_us = 3'000;
    s.priority = 8 - i;
    s.run = &nothing;
    table.push_back(s);
  }
  Scheduler scheduler(clock, table);
  ::ultrasim::testing::start_counting_allocations();
  for (int i = 0; i < 120; ++i) {
    scheduler.tick();
    clock.advance_us(16'667);
  }
  EXPECT_EQ(::ultrasim::testing::stop_counting_allocations(), 0);
}

}  // namespace
}  // namespace ultrasim::sched
