#include "ultrasim/drivers/posix/process_memory.hpp"

#include <malloc.h>
#include <unistd.h>

#include <fstream>

namespace ultrasim::drivers::posix {

std::int64_t resident_memory_kib() {
  std::ifstream statm("/proc/self/statm");
  std::int64_t size_pages = 0, resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return -1;
  return resident_pages * static_cast<std::int64_t>(sysconf(_SC_PAGESIZE)) / 1024;
}

std::int64_t heap_in_use_kib() {
  const struct mallinfo2 heap = mallinfo2();
  return static_cast<std::int64_t>((heap.uordblks + heap.hblkhd) / 1024);
}

void return_freed_memory() {
  malloc_trim(0);
}

}  // namespace ultrasim::drivers::posix
