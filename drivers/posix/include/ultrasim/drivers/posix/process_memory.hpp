#pragma once

#include <cstdint>

namespace ultrasim::drivers::posix {

// The process's resident memory in KiB (/proc/self/statm), or -1 where it cannot be read.
// Opens a file: for reports and soak runs, not inside a frame's work.
std::int64_t resident_memory_kib();

// The bytes the program holds allocated through malloc (glibc's mallinfo2: in use in its arenas
// plus its own mmapped blocks), KiB. Against resident memory it tells what the program keeps from
// what the allocator keeps for it: freed memory the allocator has not handed back stays resident.
// Walks the allocator's free lists: for reports, not inside a frame's work.
std::int64_t heap_in_use_kib();

// Hands the memory freed into the allocator's arenas back to the system (glibc's malloc_trim):
// a freed case's buffers otherwise stay resident, and where the next case's land among them
// decides how much. Walks every arena: after a case switch, not inside a frame's work.
void return_freed_memory();

}  // namespace ultrasim::drivers::posix
