#include "core/util/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

namespace reconduit {
namespace {

TEST(ParallelFor, VisitsEveryIndexOnce) {
  std::vector<std::atomic<int>> hits(1000);
  ParallelFor(
      0, hits.size(), [&](std::size_t i) { hits[i]++; }, 3);
  for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
}

TEST(ParallelFor, EmptyRangeDoesNothing) {
  int calls = 0;
  ParallelFor(5, 5, [&](std::size_t) { ++calls; });
  ParallelFor(6, 5, [&](std::size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, RethrowsFirstExceptionAndStopsStartingItems) {
  std::atomic<int> started{0};
  EXPECT_THROW(ParallelFor(
                   0, 100000,
                   [&](std::size_t i) {
                     ++started;
                     if (i == 10) throw std::runtime_error("item 10 failed");
                     // Items take a while, so that even on a loaded machine the other
                     // thread cannot run through all of them before the failure is seen.
                     std::this_thread::sleep_for(std::chrono::microseconds(100));
                   },
                   2),
               std::runtime_error);
  EXPECT_LT(started.load(), 100000);
}

TEST(EffectiveNumThreads, ExplicitRequestWins) {
  EXPECT_EQ(EffectiveNumThreads(3), 3);
  EXPECT_GE(EffectiveNumThreads(0), 1);
}

}  // namespace
}  // namespace reconduit
