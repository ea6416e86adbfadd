#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>

namespace ultrasim::drivers::posix {

// Who is inside a ThreadPool's current batch of tasks. The caller opens a batch, runs tasks
// itself, then closes it and waits only for the workers that joined while it was open: a worker
// the OS has not yet run when the tasks are all taken (a kernel thread on its core for a time
// slice: 2-8 ms twice a second on the shared host) costs the caller nothing, and joins the
// next batch instead. Waiting for every worker to acknowledge each batch held the large case's
// frames that long.
class WorkerGate {
 public:
  // The caller: a new batch that workers may join until close_and_wait().
  void open();
  // The caller: no one joins the batch any more; returns once every worker that joined it left.
  void close_and_wait();
  // A worker: waits for a batch newer than `seen` that is still open, joins it and returns true
  // (seen becomes its number); or returns false once stop() was called. It watches for the batch
  // for up to `poll_for`, yielding its core to any other thread that wants it, before it sleeps:
  // woken from the condition variable it comes ~50 µs after the batch opened on this host, most
  // of a short batch's time, and a frame's batches come in bursts (the stitched steps', the
  // B-scan's passes, the view's), each within the last's poll.
  bool join_next(std::uint64_t& seen,
                 std::chrono::microseconds poll_for = std::chrono::microseconds::zero());
  // A worker that joined: it has finished with the batch.
  void leave();
  // join_next() returns false from now on, to every worker.
  void stop();

 private:
  std::mutex mutex_;
  std::condition_variable opened_, emptied_;
  std::uint64_t batch_ = 0;  // the latest batch's number
  bool open_ = false;
  std::atomic<std::uint64_t> open_batch_{0};  // batch_ while open_, else 0: what a worker polls
  int inside_ = 0;  // workers that joined the latest batch and have not left it
  bool stopping_ = false;
};

}  // namespace ultrasim::drivers::posix
