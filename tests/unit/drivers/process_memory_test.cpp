#include "ultrasim/drivers/posix/process_memory.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace ultrasim::drivers::posix {
namespace {

constexpr std::int64_t kMib = 1024;  // in KiB

// One large block (the allocator maps it on its own) and many small ones (from its arenas): both
// count while held, and neither once freed.
TEST(HeapInUse, CountsWhatIsHeldLargeOrSmallAndNotWhatIsFreed) {
  const std::int64_t before = heap_in_use_kib();
  ASSERT_GT(before, 0);
  auto large = std::make_unique<std::vector<char>>(static_cast<std::size_t>(48 * kMib * 1024), 1);
  std::vector<std::unique_ptr<char[]>> small;
  for (int i = 0; i < 100'000; ++i) small.push_back(std::make_unique<char[]>(256));
  const std::int64_t held = heap_in_use_kib();
  EXPECT_GE(held - before, 48 * kMib + 24 * kMib);
  EXPECT_LE(held - before, 48 * kMib + 40 * kMib);  // 256 B blocks and their headers: ~26 MB
  large.reset();
  small.clear();
  small.shrink_to_fit();
  EXPECT_LT(heap_in_use_kib() - before, kMib);
}

// Small blocks freed below one still held stay in the allocator's arena, resident, until handed
// back: what a case switch leaves behind.
TEST(ReturnFreedMemory, HandsBackFreedBlocksTheAllocatorKept) {
  std::vector<std::unique_ptr<char[]>> small;
  for (int i = 0; i < 200'000; ++i) {
    small.push_back(std::make_unique<char[]>(256));
    small.back()[0] = 1;
  }
  const auto last_held = std::move(small.back());  // keeps the arena from shrinking at its top
  small.pop_back();
  const std::int64_t held = resident_memory_kib();
  small.clear();
  small.shrink_to_fit();
  const std::int64_t freed = resident_memory_kib();
  EXPECT_GT(freed, held - 8 * kMib) << "kept by the allocator, as a case switch leaves it";
  return_freed_memory();
  EXPECT_LT(resident_memory_kib(), freed - 32 * kMib);
  EXPECT_EQ(last_held[0], 1);
}

TEST(ResidentMemory, CountsTouchedPages) {
  const std::int64_t before = resident_memory_kib();
  ASSERT_GT(before, 0);
  const std::vector<char> touched(static_cast<std::size_t>(64 * kMib * 1024), 1);
  EXPECT_GE(resident_memory_kib() - before, 60 * kMib);
  EXPECT_EQ(touched.back(), 1);
}

}  // namespace
}  // namespace ultrasim::drivers::posix
