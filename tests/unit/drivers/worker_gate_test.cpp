#include "ultrasim/drivers/posix/worker_gate.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <future>
#include <thread>

namespace ultrasim::drivers::posix {
namespace {

using namespace std::chrono_literals;

// A worker the OS runs only after the caller has done every task and closed the batch: the
// caller did not wait for it, and it does not enter that batch late (its task state may already
// be the next batch's), only the next.
TEST(WorkerGate, AWorkerThatComesAfterTheBatchClosedJoinsTheNextOne) {
  WorkerGate gate;
  gate.open();
  gate.close_and_wait();  // returns at once: no worker joined
  std::uint64_t seen = 0;
  auto joined = std::async(std::launch::async, [&] { return gate.join_next(seen); });
  EXPECT_EQ(joined.wait_for(50ms), std::future_status::timeout) << "batch 1 is closed";
  gate.open();
  ASSERT_TRUE(joined.get());
  EXPECT_EQ(seen, 2u);
  gate.leave();
  gate.close_and_wait();
}

TEST(WorkerGate, TheCallerWaitsForAWorkerInsideTheBatchUntilItLeaves) {
  WorkerGate gate;
  std::atomic<bool> inside{false}, left{false};
  gate.open();
  std::thread worker([&] {
    std::uint64_t seen = 0;
    ASSERT_TRUE(gate.join_next(seen));
    inside = true;
    std::this_thread::sleep_for(30ms);
    left = true;
    gate.leave();
  });
  // The worker may not have joined yet: close only once it has (else it skips this batch).
  while (!inside) std::this_thread::yield();
  gate.close_and_wait();
  EXPECT_TRUE(left.load());
  worker.join();
}

TEST(WorkerGate, AWorkerJoinsEachBatchAtMostOnce) {
  WorkerGate gate;
  std::uint64_t seen = 0;
  gate.open();
  ASSERT_TRUE(gate.join_next(seen));
  gate.leave();
  auto again = std::async(std::launch::async, [&] { return gate.join_next(seen); });
  EXPECT_EQ(again.wait_for(50ms), std::future_status::timeout) << "still batch 1";
  gate.stop();
  EXPECT_FALSE(again.get());
}

// A worker that polls before it sleeps keeps the gate's rules: it joins a batch opened while it
// polls, or after it went to sleep, each at most once, never one already closed; stop() ends it.
TEST(WorkerGate, APollingWorkerJoinsEachOpenBatchOnce) {
  WorkerGate gate;
  std::uint64_t seen = 0;
  gate.open();
  gate.close_and_wait();  // batch 1: closed before the worker comes
  auto joined = std::async(std::launch::async, [&] { return gate.join_next(seen, 20ms); });
  EXPECT_EQ(joined.wait_for(60ms), std::future_status::timeout) << "batch 1 is closed";
  gate.open();  // batch 2: found by a sleeping worker
  ASSERT_TRUE(joined.get());
  EXPECT_EQ(seen, 2u);
  gate.leave();
  gate.close_and_wait();
  auto polled = std::async(std::launch::async, [&] { return gate.join_next(seen, 10s); });
  EXPECT_EQ(polled.wait_for(30ms), std::future_status::timeout) << "still batch 2";
  gate.open();  // batch 3: found while polling
  ASSERT_TRUE(polled.get());
  EXPECT_EQ(seen, 3u);
  gate.leave();
  auto again = std::async(std::launch::async, [&] { return gate.join_next(seen, 10ms); });
  EXPECT_EQ(again.wait_for(50ms), std::future_status::timeout) << "batch 3 only once";
  gate.stop();
  EXPECT_FALSE(again.get());
  gate.close_and_wait();
}

TEST(WorkerGate, StopReleasesAWaitingWorker) {
  WorkerGate gate;
  std::uint64_t seen = 0;
  auto joined = std::async(std::launch::async, [&] { return gate.join_next(seen); });
  gate.stop();
  EXPECT_FALSE(joined.get());
  EXPECT_FALSE(gate.join_next(seen)) << "and every later one";
}

}  // namespace
}  // namespace ultrasim::drivers::posix
