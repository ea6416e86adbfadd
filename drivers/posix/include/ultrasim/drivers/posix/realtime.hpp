#pragma once

// What the kiosk asks of the OS for its frame threads, and what it got. Each part is tried on its
// own; a part the OS refuses (no privileges, a container's limits, a CPU that is not there) is
// reported with the reason, never fatal: the kiosk runs without it, only with more jitter.

#include <string>

namespace ultrasim::drivers::posix {

struct RealtimeRequest {
  // mlockall(MCL_CURRENT | MCL_FUTURE): no page faults in the middle of a frame.
  bool lock_memory = true;
  // SCHED_FIFO for the frame threads at this priority (1-99): above every normal task, far
  // below the kernel's own threads (50) so interrupts still get served.
  bool fifo = true;
  int fifo_priority = 10;
  // Each frame thread on its own CPU (thread i on the i-th CPU the process may use, wrapping).
  bool pin_to_cores = true;
};

// What one thread got.
struct ThreadRealtime {
  int cpu = -1;         // the CPU it is pinned to, or -1
  bool fifo = false;    // running SCHED_FIFO
  std::string refused;  // what the OS refused and why ("" when everything asked was granted)
};

// Applies the request's scheduling to the calling thread as frame thread `index`: pinned to the
// index-th CPU (wrapping) of those it may run on. A new thread starts with its creator's CPUs, so
// pin a thread only after the threads it creates have pinned themselves. Allocates (the
// message); call once when the thread starts.
ThreadRealtime make_this_thread_realtime(const RealtimeRequest& request, int index);

// Locks the process's memory if asked; returns "" or what was refused and why.
std::string lock_process_memory(const RealtimeRequest& request);

// One line for logs and reports: "cpu 0 SCHED_FIFO 10" or "not pinned, SCHED_OTHER (...)".
std::string describe(const ThreadRealtime& thread, const RealtimeRequest& request);

}  // namespace ultrasim::drivers::posix
