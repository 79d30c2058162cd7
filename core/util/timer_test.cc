#include "core/util/timer.h"

#include <gtest/gtest.h>

#include <cstring>
#include <sys/mman.h>
#include <thread>
#include <vector>

namespace reconduit {
namespace {

constexpr std::int64_t kMiB = 1 << 20;

TEST(Timer, MeasuresElapsedTime) {
  Timer timer;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_GE(timer.ElapsedSeconds(), 0.019);
  timer.Restart();
  EXPECT_LT(timer.ElapsedSeconds(), 0.019);
}

TEST(Memory, PeakGrowsWithAllocation) {
  const std::int64_t before = PeakMemoryBytes();
  EXPECT_GT(before, 0);
  std::vector<char> block(64 << 20, 1);  // 64 MiB, touched.
  EXPECT_GE(PeakMemoryBytes(), before + (32 << 20)) << block[block.size() / 2];
  EXPECT_GT(CurrentMemoryBytes(), 0);
}

// Maps `bytes`, writes every page and unmaps them, so they leave the resident set whatever the
// allocator does with freed blocks (AddressSanitizer keeps them in quarantine); returns a byte
// read back so nothing is elided.
int TouchAndFree(std::int64_t bytes) {
  const auto size = static_cast<std::size_t>(bytes);
  void* block = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (block == MAP_FAILED) return -1;
  std::memset(block, 7, size);
  const int value = static_cast<volatile char*>(block)[size / 2];
  munmap(block, size);
  return value;
}

TEST(StagePeakMemory, EachStageHasItsOwnPeakAndTheProcessKeepsTheHighest) {
  std::int64_t first_peak = 0;
  {
    const StagePeakMemory first;
    if (!first.Own()) GTEST_SKIP() << "/proc/self/clear_refs cannot be written here";
    EXPECT_EQ(TouchAndFree(200 * kMiB), 7);
    first_peak = first.PeakBytes();
  }
  const std::int64_t resident_before_second = CurrentMemoryBytes();
  const StagePeakMemory second;
  ASSERT_TRUE(second.Own());
  EXPECT_EQ(TouchAndFree(20 * kMiB), 7);
  const std::int64_t second_peak = second.PeakBytes();

  EXPECT_GE(first_peak, 200 * kMiB);
  // The second stage saw its 20 MiB on top of what the process held when it began, not the
  // first stage's 200 MiB.
  EXPECT_GE(second_peak, resident_before_second + 19 * kMiB);
  EXPECT_LT(second_peak, resident_before_second + 60 * kMiB);
  EXPECT_LT(second_peak, first_peak - 100 * kMiB);
  // The process's peak is the first stage's, although the kernel's mark was reset since.
  EXPECT_GE(PeakMemoryBytes(), first_peak);
  EXPECT_GE(PeakMemoryBytes(), second_peak);
}

TEST(StagePeakMemory, AStageBegunMeanwhileTakesTheMarkOver) {
  const StagePeakMemory outer;
  if (!outer.Own()) GTEST_SKIP() << "/proc/self/clear_refs cannot be written here";
  EXPECT_EQ(TouchAndFree(100 * kMiB), 7);
  const StagePeakMemory inner;
  EXPECT_TRUE(inner.Own());
  // The outer stretch's own mark is gone: it says so and reports the process's peak, which
  // still includes its 100 MiB.
  EXPECT_FALSE(outer.Own());
  EXPECT_EQ(outer.PeakBytes(), PeakMemoryBytes());
  EXPECT_GE(outer.PeakBytes(), 100 * kMiB);
  EXPECT_LT(inner.PeakBytes(), outer.PeakBytes() - 50 * kMiB);
}

}  // namespace
}  // namespace reconduit
