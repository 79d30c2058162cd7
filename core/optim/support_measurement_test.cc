#include "core/optim/support_measurement.h"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

namespace reconduit {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(InlierSupportMeasurer, CountsInliersAndSumsTheirResiduals) {
  const InlierSupportMeasurer measurer;
  const auto support = measurer.Evaluate({0.5, 1.0, 2.0, kNaN, 0.25}, /*max_residual=*/1.0);
  EXPECT_EQ(support.num_inliers, 3u);
  EXPECT_DOUBLE_EQ(support.residual_sum, 1.75);
  EXPECT_EQ(InlierSupportMeasurer::Support().num_inliers, 0u);
}

TEST(InlierSupportMeasurer, MoreInliersWinThenSmallerSum) {
  const InlierSupportMeasurer m;
  EXPECT_TRUE(m.IsLeftBetter({3, 10.0}, {2, 0.0}));
  EXPECT_FALSE(m.IsLeftBetter({2, 0.0}, {3, 10.0}));
  EXPECT_TRUE(m.IsLeftBetter({3, 1.0}, {3, 2.0}));
  EXPECT_FALSE(m.IsLeftBetter({3, 2.0}, {3, 2.0}));
  // Any evaluated support beats the default.
  EXPECT_TRUE(m.IsLeftBetter(m.Evaluate({5.0}, 1.0), InlierSupportMeasurer::Support()));
}

TEST(MEstimatorSupportMeasurer, TruncatesResidualsAtTheThreshold) {
  const MEstimatorSupportMeasurer measurer;
  const auto support = measurer.Evaluate({0.5, 1.0, 2.0, kNaN, 0.25}, /*max_residual=*/1.0);
  EXPECT_EQ(support.num_inliers, 3u);
  EXPECT_DOUBLE_EQ(support.score, 0.5 + 1.0 + 1.0 + 1.0 + 0.25);
  EXPECT_TRUE(measurer.IsLeftBetter({1, 1.0}, {5, 2.0}));
  EXPECT_TRUE(
      measurer.IsLeftBetter(measurer.Evaluate({9.0}, 1.0), MEstimatorSupportMeasurer::Support()));
}

}  // namespace
}  // namespace reconduit
