#pragma once

#include <cstdint>

namespace ultrasim::drivers::posix {

// The process's resident memory in KiB (/proc/self/statm), or -1 where it cannot be read.
// Opens a file: for reports and soak runs, not inside a frame's work.
std::int64_t resident_memory_kib();

}  // namespace ultrasim::drivers::posix
