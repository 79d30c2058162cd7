#include "worker/memory_budget.h"

#include "core/util/timer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace reconduit {
namespace {

using namespace std::chrono_literals;

TEST(MachineMemoryBytes, PositiveAndAboveWhatWeHold) {
  const std::int64_t machine = MachineMemoryBytes();
  EXPECT_GT(machine, CurrentMemoryBytes());
  EXPECT_EQ(DefaultMemoryBudgetBytes(), machine / 4 * 3);
}

TEST(FormatMemory, MiBAndGiB) {
  EXPECT_EQ(FormatMemory(std::int64_t{300} << 20), "300 MiB");
  EXPECT_EQ(FormatMemory(std::int64_t{3} << 29), "1.50 GiB");
}

TEST(MemoryWatch, CallsOnceWhenOverAndNeverWhenUnder) {
  std::atomic<int> calls{0};
  std::atomic<std::int64_t> seen{0};
  const std::int64_t baseline = CurrentMemoryBytes();
  {
    MemoryWatch under(baseline + (std::int64_t{1} << 30), 5ms, [&](std::int64_t) { ++calls; });
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(calls, 0);
  {
    MemoryWatch over(baseline + (std::int64_t{64} << 20), 5ms, [&](std::int64_t resident) {
      seen = resident;
      ++calls;
    });
    std::vector<char> held(std::size_t{128} << 20, '\1');  // Touched: resident.
    for (int i = 0; i < 200 && calls == 0; ++i) std::this_thread::sleep_for(5ms);
    std::this_thread::sleep_for(30ms);
    EXPECT_EQ(held[12345], '\1');
  }
  EXPECT_EQ(calls, 1);
  EXPECT_GT(seen, baseline + (std::int64_t{64} << 20));
}

TEST(MemoryWatch, NoBudgetNoThread) {
  std::atomic<int> calls{0};
  MemoryWatch none(0, 1ms, [&](std::int64_t) { ++calls; });
  std::this_thread::sleep_for(10ms);
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace reconduit
