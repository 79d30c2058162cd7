#include "core/util/progress.h"

#include "core/util/parallel.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace reconduit {
namespace {

TEST(Progress, NullObjectCounts) {
  Progress progress;
  progress.Restart(10, "images");
  progress.Advance(3);
  EXPECT_EQ(progress.done(), 3u);
  EXPECT_DOUBLE_EQ(progress.fraction(), 0.3);
  progress.Advance(100);
  EXPECT_EQ(progress.done(), 10u) << "clamped to total";
  EXPECT_EQ(progress.message(), "images");
}

TEST(Progress, RestartAndFinishAlwaysReport) {
  std::vector<ProgressUpdate> updates;
  Progress progress([&](const ProgressUpdate& u) { updates.push_back(u); }, std::chrono::hours(1));
  progress.Restart(4, "pairs");
  progress.Advance();  // Throttled: the first report already set the next time an hour away.
  progress.Advance();
  progress.Finish();
  ASSERT_EQ(updates.size(), 2u);
  EXPECT_EQ(updates[0].message, "pairs");
  EXPECT_EQ(updates[0].done, 0u);
  EXPECT_DOUBLE_EQ(updates[1].fraction, 1.0);
}

TEST(Progress, UnthrottledReportsEveryAdvance) {
  int reports = 0;
  Progress progress([&](const ProgressUpdate&) { ++reports; }, std::chrono::milliseconds(0));
  progress.Restart(3, "x");
  progress.Advance();
  progress.Advance();
  progress.Advance();
  EXPECT_EQ(reports, 4);
}

TEST(Progress, ConcurrentAdvanceCountsEveryUnit) {
  std::size_t last_done = 0;
  Progress progress([&](const ProgressUpdate& u) { last_done = u.done; },
                    std::chrono::milliseconds(0));
  progress.Restart(10000, "items");
  ParallelFor(
      0, 10000, [&](std::size_t) { progress.Advance(); }, 4);
  EXPECT_EQ(progress.done(), 10000u);
  progress.Finish();
  EXPECT_EQ(last_done, 10000u);
}

TEST(Progress, ZeroTotalHasZeroFraction) {
  Progress progress;
  progress.Restart(0, "nothing");
  EXPECT_DOUBLE_EQ(progress.fraction(), 0.0);
}

}  // namespace
}  // namespace reconduit
