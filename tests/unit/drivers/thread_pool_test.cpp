#include "ultrasim/drivers/posix/thread_pool.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <latch>
#include <numeric>
#include <set>
#include <thread>
#include <vector>

namespace ultrasim::drivers::posix {
namespace {

TEST(ThreadPool, RunsEveryTaskExactlyOnce) {
  ThreadPool pool(2);
  EXPECT_EQ(pool.thread_count(), 2);
  for (int round = 0; round < 200; ++round) {
    std::vector<std::atomic<int>> hits(97);
    hal::parallel_for(pool, 97, [&](int i) { hits[i].fetch_add(1); });
    for (auto& h : hits) ASSERT_EQ(h.load(), 1);
  }
}

// Short runs back to back: workers often wake after the caller has done every task and moved on
// (WorkerGate); none may run a task of a batch it came late to, or miss one it joined.
TEST(ThreadPool, ShortRunsBackToBackRunEachTaskOnceWhereverTheWorkersAre) {
  ThreadPool pool(3);
  std::vector<std::atomic<int>> hits(3 * 20000);
  for (int round = 0; round < 20000; ++round) {
    hal::parallel_for(pool, 3, [&](int i) { hits[3 * round + i].fetch_add(1); });
  }
  for (const auto& h : hits) ASSERT_EQ(h.load(), 1);
}

TEST(ThreadPool, UsesMoreThanOneThreadForSlowTasks) {
  ThreadPool pool(2);
  std::mutex m;
  std::set<std::thread::id> threads;
  hal::parallel_for(pool, 8, [&](int) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    std::lock_guard lock(m);
    threads.insert(std::this_thread::get_id());
  });
  EXPECT_EQ(threads.size(), 2u);
}

TEST(ThreadPool, ResultsMatchTheInlineJobSystem) {
  ThreadPool pool(3);
  hal::InlineJobSystem inline_jobs;
  std::vector<long> a(1000), b(1000);
  hal::parallel_for(pool, 1000, [&](int i) { a[i] = static_cast<long>(i) * i; });
  hal::parallel_for(inline_jobs, 1000, [&](int i) { b[i] = static_cast<long>(i) * i; });
  EXPECT_EQ(a, b);
}

TEST(ThreadPool, ZeroAndOneThreadsRunOnTheCaller) {
  ThreadPool pool(0);
  EXPECT_EQ(pool.thread_count(), 1);
  int sum = 0;
  hal::parallel_for(pool, 10, [&](int i) { sum += i; });  // no race: one thread
  EXPECT_EQ(sum, 45);
  hal::parallel_for(pool, 0, [&](int) { sum = -1; });
  EXPECT_EQ(sum, 45);
}

TEST(ThreadPool, AMissingJobSystemRunsTheTasksInOrderOnTheCaller) {
  std::vector<int> order;
  hal::parallel_for(static_cast<hal::JobSystem*>(nullptr), 5, [&](int i) { order.push_back(i); });
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4}));
  ThreadPool pool(2);
  std::vector<std::atomic<int>> hits(64);
  hal::JobSystem* jobs = &pool;
  hal::parallel_for(jobs, 64, [&](int i) { hits[i].fetch_add(1); });
  for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
}

// The background lane: one task at a time, on a thread of its own at idle priority.
TEST(ThreadPool, RunsABackgroundTaskOnAnIdlePriorityThreadOfItsOwn) {
  ThreadPool pool(2);
  struct Seen {
    std::thread::id thread;
    int policy = -1;
  } seen;
  const auto look = [](void* context) {
    auto& s = *static_cast<Seen*>(context);
    s.thread = std::this_thread::get_id();
    sched_param param{};
    pthread_getschedparam(pthread_self(), &s.policy, &param);
  };
  ASSERT_TRUE(pool.post_background(look, &seen));
  pool.background().wait_idle();
  EXPECT_NE(seen.thread, std::this_thread::get_id());
  EXPECT_NE(seen.thread, std::thread::id());
  // Lowering one's own priority needs no privilege on Linux.
  EXPECT_TRUE(pool.background().idle_priority());
  EXPECT_EQ(seen.policy, SCHED_IDLE);
}

TEST(ThreadPool, TakesOneBackgroundTaskAtATimeAndRunsEveryOnePosted) {
  std::latch started(1), release(1);
  std::atomic<int> runs{0};
  struct Gate {
    std::latch* started;
    std::latch* release;
    std::atomic<int>* runs;
  } gate{&started, &release, &runs};
  const auto wait_at_gate = [](void* context) {
    auto& g = *static_cast<Gate*>(context);
    g.started->count_down();
    g.release->wait();
    g.runs->fetch_add(1);
  };
  {
    ThreadPool pool(2);
    ASSERT_TRUE(pool.post_background(wait_at_gate, &gate));
    started.wait();
    EXPECT_FALSE(pool.post_background(wait_at_gate, &gate)) << "one is running";
    release.count_down();
    pool.background().wait_idle();
    EXPECT_EQ(runs.load(), 1);
    EXPECT_TRUE(pool.post_background(wait_at_gate, &gate)) << "idle again";
  }  // the pool runs the second before it goes (the gates are open now)
  EXPECT_EQ(runs.load(), 2);
  hal::InlineJobSystem inline_jobs;
  EXPECT_FALSE(inline_jobs.post_background(wait_at_gate, &gate)) << "no background thread";
}

}  // namespace
}  // namespace ultrasim::drivers::posix
