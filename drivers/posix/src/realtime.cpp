#include "ultrasim/drivers/posix/realtime.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace ultrasim::drivers::posix {

namespace {

std::string because(const char* what, int error) {
  return std::string(what) + ": " + std::strerror(error);
}

void append(std::string& to, const std::string& what) {
  to += to.empty() ? what : "; " + what;
}

// The index-th CPU (wrapping) of those this process may run on, or -1.
int allowed_cpu(int index) {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof(allowed), &allowed) != 0) return -1;
  const int count = CPU_COUNT(&allowed);
  if (count == 0) return -1;
  int wanted = index % count;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
    if (CPU_ISSET(cpu, &allowed) && wanted-- == 0) return cpu;
  }
  return -1;
}

}  // namespace

ThreadRealtime make_this_thread_realtime(const RealtimeRequest& request, int index) {
  ThreadRealtime out;
  if (request.pin_to_cores) {
    const int cpu = allowed_cpu(index);
    if (cpu < 0) {
      append(out.refused, "pinning: no CPU allowed");
    } else {
      cpu_set_t one;
      CPU_ZERO(&one);
      CPU_SET(cpu, &one);
      const int error = pthread_setaffinity_np(pthread_self(), sizeof(one), &one);
      if (error == 0) {
        out.cpu = cpu;
      } else {
        append(out.refused, because("pinning", error));
      }
    }
  }
  if (request.fifo) {
    sched_param param{};
    param.sched_priority = request.fifo_priority;
    const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    if (error == 0) {
      out.fifo = true;
    } else {
      append(out.refused, because("SCHED_FIFO", error));
    }
  }
  return out;
}

std::string lock_process_memory(const RealtimeRequest& request) {
  if (!request.lock_memory) return "";
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return "";
  return because("mlockall", errno);
}

std::string describe(const ThreadRealtime& thread, const RealtimeRequest& request) {
  std::string s = thread.cpu >= 0 ? "cpu " + std::to_string(thread.cpu) : "not pinned";
  s += thread.fifo ? ", SCHED_FIFO " + std::to_string(request.fifo_priority) : ", SCHED_OTHER";
  if (!thread.refused.empty()) s += " (" + thread.refused + ")";
  return s;
}

}  // namespace ultrasim::drivers::posix
