#include "core/util/timer.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace reconduit {
namespace {

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

}  // namespace
}  // namespace reconduit
