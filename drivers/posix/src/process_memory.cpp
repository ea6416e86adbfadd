#include "ultrasim/drivers/posix/process_memory.hpp"

#include <unistd.h>

#include <fstream>

namespace ultrasim::drivers::posix {

std::int64_t resident_memory_kib() {
  std::ifstream statm("/proc/self/statm");
  std::int64_t size_pages = 0, resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return -1;
  return resident_pages * static_cast<std::int64_t>(sysconf(_SC_PAGESIZE)) / 1024;
}

}  // namespace ultrasim::drivers::posix
