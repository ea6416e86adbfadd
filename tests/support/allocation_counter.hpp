#pragma once

// Counts heap allocations (global operator new) made by the calling thread while counting is
// on. The replacement operators live in allocation_counter.cpp, a translation unit of their own
// so the compiler cannot inline them into (and misjudge) their callers.

namespace ultrasim::testing {

void start_counting_allocations();
// Stops counting and returns the number of allocations since start_counting_allocations().
long stop_counting_allocations();

}  // namespace ultrasim::testing
