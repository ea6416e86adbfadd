// The frame's parallel runs while another thread holds a core now and then: ThreadPool (a run
// waits only for the workers that joined it, WorkerGate) against the protocol it replaced, in
// which every worker acknowledged every run before the caller went on (the reference, below).
// Scene: two frame threads (the caller and one worker, as in the kiosk) and a third thread that
// spins `burst_us` and sleeps `gap_us` in turn (on the shared host a kernel thread, kdamond,
// holds a core for a 3-8 ms slice about twice a second), all on the same cores, unpinned. Each
// run: two tasks of ~`task_us` spinning, the frame's shape (two sub-volumes side by side); the two
// pools alternate run by run, so both see the same machine. Counters: each one's run time, p50,
// p99 and max (µs), and the reference's over ThreadPool's. BM_RunBursts: the workers' watch for
// the next run before they sleep, against workers that sleep at once.
//   build/ci/tests/bench/thread_pool_bench

#include <benchmark/benchmark.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <numeric>
#include <thread>
#include <vector>

#include "ultrasim/drivers/posix/realtime.hpp"
#include "ultrasim/drivers/posix/thread_pool.hpp"

namespace {

using namespace ultrasim;
using Clock = std::chrono::steady_clock;

void spin_for(std::chrono::microseconds span) {
  const auto until = Clock::now() + span;
  while (Clock::now() < until) {
  }
}

// The reference: run() returns once every worker has acknowledged the run, whether or not it
// took a task (the thread pool's protocol before WorkerGate).
class AcknowledgingPool final : public hal::JobSystem {
 public:
  explicit AcknowledgingPool(int thread_count) {
    for (int i = 0; i + 1 < thread_count; ++i) workers_.emplace_back([this] { worker_loop(); });
  }
  ~AcknowledgingPool() override {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    for (auto& w : workers_) w.join();
  }
  AcknowledgingPool(const AcknowledgingPool&) = delete;
  AcknowledgingPool& operator=(const AcknowledgingPool&) = delete;

  int thread_count() const override { return static_cast<int>(workers_.size()) + 1; }
  void run(int task_count, void (*task)(void*, int), void* context) override {
    {
      std::lock_guard lock(mutex_);
      task_ = task;
      context_ = context;
      task_count_ = task_count;
      next_.store(0, std::memory_order_relaxed);
      busy_workers_ = static_cast<int>(workers_.size());
      ++batch_;
    }
    wake_.notify_all();
    drain();
    std::unique_lock lock(mutex_);
    done_.wait(lock, [&] { return busy_workers_ == 0; });
  }

 private:
  void drain() {
    for (int i = next_.fetch_add(1); i < task_count_; i = next_.fetch_add(1)) task_(context_, i);
  }
  void worker_loop() {
    std::uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return stopping_ || batch_ != seen; });
        if (stopping_) return;
        seen = batch_;
      }
      drain();
      std::lock_guard lock(mutex_);
      if (--busy_workers_ == 0) done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::uint64_t batch_ = 0;
  int busy_workers_ = 0;
  bool stopping_ = false;
  void (*task_)(void*, int) = nullptr;
  void* context_ = nullptr;
  int task_count_ = 0;
  std::atomic<int> next_{0};
};

// Spins `burst` then sleeps `gap`, until destroyed.
class CoreHog {
 public:
  CoreHog(std::chrono::microseconds burst, std::chrono::microseconds gap)
      : thread_([this, burst, gap] {
          while (!stop_.load(std::memory_order_relaxed)) {
            spin_for(burst);
            std::this_thread::sleep_for(gap);
          }
        }) {}
  ~CoreHog() {
    stop_ = true;
    thread_.join();
  }
  CoreHog(const CoreHog&) = delete;
  CoreHog& operator=(const CoreHog&) = delete;

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

double percentile(std::vector<double> values, double p) {
  std::ranges::sort(values);
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

void BM_RunWhileACoreIsTaken(benchmark::State& state) {
  const std::chrono::microseconds task(state.range(0));
  const std::chrono::microseconds burst(state.range(1)), gap(state.range(2));
  drivers::posix::ThreadPool pool(2);
  AcknowledgingPool reference(2);
  const CoreHog hog(burst, gap);
  const auto timed_run = [&](hal::JobSystem& jobs) {
    const auto t0 = Clock::now();
    hal::parallel_for(jobs, 2, [&](int) { spin_for(task); });
    return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
  };
  std::vector<double> ours, theirs;
  for (auto _ : state) {
    const double a = timed_run(pool);
    const double b = timed_run(reference);
    ours.push_back(a);
    theirs.push_back(b);
    state.SetIterationTime((a + b) * 1e-6);
    spin_for(std::chrono::microseconds(500));  // the frame's other work between its runs
  }
  state.counters["pool_p50_us"] = percentile(ours, 0.5);
  state.counters["pool_p99_us"] = percentile(ours, 0.99);
  state.counters["pool_max_us"] = percentile(ours, 1.0);
  state.counters["ref_p50_us"] = percentile(theirs, 0.5);
  state.counters["ref_p99_us"] = percentile(theirs, 0.99);
  state.counters["ref_max_us"] = percentile(theirs, 1.0);
  state.counters["ref/pool_p99"] = percentile(theirs, 0.99) / percentile(ours, 0.99);
  state.counters["ref/pool_mean"] = std::accumulate(theirs.begin(), theirs.end(), 0.0) /
                                    std::accumulate(ours.begin(), ours.end(), 0.0);
}

BENCHMARK(BM_RunWhileACoreIsTaken)
    ->ArgNames({"task_us", "burst_us", "gap_us"})
    ->Args({200, 0, 10'000})       // no hog to speak of: the protocols' own cost
    ->Args({200, 3'000, 10'000})   // a core taken 3 ms in every 13
    ->Args({200, 8'000, 500'000})  // the host's kernel thread: 8 ms twice a second
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->MinTime(5.0);

// A frame's runs come in bursts: the stitched steps' batches, the B-scan's passes, the view's,
// a few tens of microseconds apart, then the rendering (milliseconds) without any. ThreadPool's
// workers watch kPollBeforeSleep for the next run before they sleep; the reference is the same
// pool whose workers sleep at once (poll 0), woken through the condition variable each run. The
// pools alternate burst by burst; `pinned` 1 puts the caller and the worker on cores of their
// own (the kiosk's --realtime, without SCHED_FIFO), 0 leaves them to the OS. Counters: each
// one's run time p50 / p90 (µs), and the reference's mean over ThreadPool's.
void BM_RunBursts(benchmark::State& state) {
  const std::chrono::microseconds task(state.range(0)), between(state.range(1));
  const bool pinned = state.range(2) != 0;
  constexpr int kRunsABurst = 8;
  drivers::posix::RealtimeRequest cores;
  cores.lock_memory = false;
  cores.fifo = false;
  const drivers::posix::RealtimeRequest* request = pinned ? &cores : nullptr;
  drivers::posix::ThreadPool pool(2, request);
  drivers::posix::ThreadPool reference(2, request, std::chrono::microseconds::zero());
  if (pinned) drivers::posix::make_this_thread_realtime(cores, 0);
  std::vector<double> ours, theirs;
  const auto burst = [&](hal::JobSystem& jobs, std::vector<double>& times) {
    double total = 0.0;
    for (int r = 0; r < kRunsABurst; ++r) {
      const auto t0 = Clock::now();
      hal::parallel_for(jobs, 2, [&](int) { spin_for(task); });
      const double us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
      times.push_back(us);
      total += us;
      spin_for(between);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the rendering
    return total;
  };
  for (auto _ : state) {
    const double a = burst(pool, ours);
    const double b = burst(reference, theirs);
    state.SetIterationTime((a + b) * 1e-6);
  }
  if (pinned) {
    // Back on every core, as the thread came.
    cpu_set_t all;
    CPU_ZERO(&all);
    for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) CPU_SET(cpu, &all);
    sched_setaffinity(0, sizeof(all), &all);
  }
  state.counters["pool_p50_us"] = percentile(ours, 0.5);
  state.counters["pool_p90_us"] = percentile(ours, 0.9);
  state.counters["ref_p50_us"] = percentile(theirs, 0.5);
  state.counters["ref_p90_us"] = percentile(theirs, 0.9);
  state.counters["ref/pool_mean"] = std::accumulate(theirs.begin(), theirs.end(), 0.0) /
                                    std::accumulate(ours.begin(), ours.end(), 0.0);
}

BENCHMARK(BM_RunBursts)
    ->ArgNames({"task_us", "between_us", "pinned"})
    ->Args({50, 10, 0})   // the view's passes
    ->Args({300, 20, 0})  // two sub-volumes' steps side by side
    ->Args({50, 10, 1})
    ->Args({300, 20, 1})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->MinTime(3.0);

}  // namespace

BENCHMARK_MAIN();
