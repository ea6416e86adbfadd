// Realtime set-up reports what the OS really granted: checked against the OS's own view of the
// thread (affinity, policy), whether or not this machine grants it.

#include "ultrasim/drivers/posix/realtime.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <thread>

#include "ultrasim/drivers/posix/thread_pool.hpp"

namespace ultrasim::drivers::posix {
namespace {

// The OS's view of the calling thread.
struct Observed {
  int only_cpu = -1;  // the single CPU it may run on, or -1 when several
  bool fifo = false;
};

Observed observe_this_thread() {
  Observed o;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (pthread_getaffinity_np(pthread_self(), sizeof(set), &set) == 0 && CPU_COUNT(&set) == 1) {
    for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
      if (CPU_ISSET(cpu, &set)) o.only_cpu = cpu;
    }
  }
  int policy = 0;
  sched_param param{};
  o.fifo = pthread_getschedparam(pthread_self(), &policy, &param) == 0 && policy == SCHED_FIFO;
  return o;
}

TEST(Realtime, TheReportMatchesWhatTheThreadGot) {
  // On a thread of its own (it ends with the test), at the lowest FIFO priority.
  RealtimeRequest request;
  request.fifo_priority = 1;
  ThreadRealtime got;
  Observed seen;
  std::thread([&] {
    got = make_this_thread_realtime(request, 1);
    seen = observe_this_thread();
  }).join();
  EXPECT_EQ(got.cpu, seen.only_cpu);
  EXPECT_EQ(got.fifo, seen.fifo);
  if (got.cpu < 0 || !got.fifo) {
    EXPECT_FALSE(got.refused.empty()) << "a refusal says why";
  } else {
    EXPECT_TRUE(got.refused.empty()) << got.refused;
  }
  const std::string line = describe(got, request);
  EXPECT_NE(line.find(got.fifo ? "SCHED_FIFO 1" : "SCHED_OTHER"), std::string::npos) << line;
  std::printf("realtime here: %s\n", line.c_str());
}

TEST(Realtime, NothingAskedNothingChanged) {
  RealtimeRequest none;
  none.lock_memory = none.fifo = none.pin_to_cores = false;
  ThreadRealtime got;
  Observed seen;
  std::thread([&] {
    got = make_this_thread_realtime(none, 0);
    seen = observe_this_thread();
  }).join();
  EXPECT_EQ(got.cpu, -1);
  EXPECT_FALSE(got.fifo);
  EXPECT_TRUE(got.refused.empty());
  EXPECT_FALSE(seen.fifo);
  EXPECT_EQ(lock_process_memory(none), "");
}

TEST(Realtime, PoolWorkersArePinnedToTheirOwnCoresAndReportIt) {
  RealtimeRequest request;
  request.fifo = false;  // the pool's workers then share the machine fairly with other tests
  ThreadPool pool(2, &request);
  ASSERT_EQ(pool.worker_realtime().size(), 1u);
  const ThreadRealtime& worker = pool.worker_realtime()[0];
  EXPECT_FALSE(worker.fifo);
  // Two tasks that each wait for the other to start: the caller runs one, the worker the other,
  // and each records the OS's view of its thread.
  struct Probe {
    std::atomic<int> started{0};
    Observed seen[2];
  } probe;
  pool.run(
      2,
      [](void* context, int i) {
        auto* p = static_cast<Probe*>(context);
        p->started.fetch_add(1);
        while (p->started.load() < 2) std::this_thread::yield();
        p->seen[i] = observe_this_thread();
      },
      &probe);
  if (worker.cpu >= 0) {
    EXPECT_TRUE(worker.refused.empty()) << worker.refused;
    EXPECT_TRUE(probe.seen[0].only_cpu == worker.cpu || probe.seen[1].only_cpu == worker.cpu)
        << "the worker runs only on cpu " << worker.cpu;
  } else {
    EXPECT_FALSE(worker.refused.empty());
  }
}

}  // namespace
}  // namespace ultrasim::drivers::posix
