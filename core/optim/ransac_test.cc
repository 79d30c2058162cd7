#include "core/optim/ransac.h"

#include "core/optim/line_estimator_test_util.h"
#include "core/util/cancel.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace reconduit {
namespace {

using testing_util::Line;
using testing_util::LineEstimator;

// 50 % outliers: inliers on y = 2x + 1 (plus optional noise), outliers at least 1.0 away from
// the line, interleaved so that position says nothing.
struct LineData {
  std::vector<double> x, y;
  std::vector<char> is_inlier;
};

LineData MakeLineData(int num_inliers, int num_outliers, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-10.0, 10.0);
  std::uniform_real_distribution<double> uoff(1.0, 20.0);
  std::normal_distribution<double> gauss(0.0, noise);
  std::bernoulli_distribution sign(0.5);
  LineData data;
  const int total = num_inliers + num_outliers;
  for (int i = 0; i < total; ++i) {
    const bool inlier = (i % 2 == 0 && i / 2 < num_inliers) || i / 2 >= num_outliers;
    const double x = ux(rng);
    double y = 2.0 * x + 1.0;
    if (inlier) {
      if (noise > 0) y += gauss(rng);
    } else {
      y += sign(rng) ? uoff(rng) : -uoff(rng);
    }
    data.x.push_back(x);
    data.y.push_back(y);
    data.is_inlier.push_back(inlier ? 1 : 0);
  }
  return data;
}

TEST(RANSACReport, DefaultsReadAsFailure) {
  const RANSAC<LineEstimator>::Report report;
  EXPECT_FALSE(report.success);
  EXPECT_FALSE(report.canceled);
  EXPECT_EQ(report.message, "not run");
  EXPECT_EQ(report.num_trials, 0u);
  EXPECT_EQ(report.support.num_inliers, 0u);
  EXPECT_TRUE(report.inlier_mask.empty());
}

TEST(RANSAC, RecoversLineAndExactInlierSetWithHalfOutliers) {
  const LineData data = MakeLineData(100, 100, /*noise=*/0.0, /*seed=*/1);
  RANSACOptions options;
  options.max_error = 0.1;
  const auto report = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(report.success) << report.message;
  EXPECT_TRUE(report.message.empty());
  EXPECT_NEAR(report.model.slope, 2.0, 1e-9);
  EXPECT_NEAR(report.model.offset, 1.0, 1e-9);
  EXPECT_EQ(report.support.num_inliers, 100u);
  EXPECT_EQ(report.inlier_mask, data.is_inlier);
  EXPECT_GT(report.num_trials, 0u);
  EXPECT_LE(report.num_trials, options.max_num_trials);
}

TEST(RANSAC, SameSeedGivesSameReportDifferentSeedStillSucceeds) {
  const LineData data = MakeLineData(60, 60, /*noise=*/0.05, /*seed=*/2);
  RANSACOptions options;
  options.max_error = 0.3;
  const auto a = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  const auto b = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.num_trials, b.num_trials);
  EXPECT_EQ(a.inlier_mask, b.inlier_mask);
  EXPECT_EQ(a.model.slope, b.model.slope);  // Bitwise identical.
  EXPECT_EQ(a.model.offset, b.model.offset);

  // Other seeds draw other samples: with noisy data the minimal models differ.
  bool any_different = false;
  for (std::uint64_t seed = 100; seed < 105; ++seed) {
    options.random_seed = seed;
    const auto c = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
    ASSERT_TRUE(c.success);
    EXPECT_NEAR(c.model.slope, 2.0, 0.05);
    any_different |= c.model.slope != a.model.slope;
  }
  EXPECT_TRUE(any_different);
}

TEST(RANSAC, TooFewPointsFailsWithMessage) {
  const auto report = RANSAC<LineEstimator>(RANSACOptions()).Estimate({1.0}, {2.0});
  EXPECT_FALSE(report.success);
  EXPECT_NE(report.message.find("at least 2"), std::string::npos) << report.message;
  EXPECT_TRUE(report.inlier_mask.empty());

  const auto empty = RANSAC<LineEstimator>(RANSACOptions()).Estimate({}, {});
  EXPECT_FALSE(empty.success);
}

TEST(RANSAC, DegenerateDataFailsWithoutThrowing) {
  // All x equal: every sample is degenerate and the solver returns no model.
  const std::vector<double> x(20, 3.0);
  std::vector<double> y;
  for (int i = 0; i < 20; ++i) y.push_back(i);
  RANSACOptions options;
  options.max_num_trials = 50;
  const auto report = RANSAC<LineEstimator>(options).Estimate(x, y);
  EXPECT_FALSE(report.success);
  EXPECT_FALSE(report.message.empty());
  EXPECT_EQ(report.num_trials, 50u);
}

TEST(RANSAC, MismatchedSizesThrow) {
  EXPECT_THROW(RANSAC<LineEstimator>(RANSACOptions()).Estimate({1.0, 2.0}, {1.0}), CheckError);
}

TEST(RANSAC, InvalidOptionsThrowInConstructor) {
  RANSACOptions options;
  options.max_error = -1.0;
  EXPECT_THROW(RANSAC<LineEstimator>{options}, CheckError);
}

TEST(RANSAC, CanceledTokenStopsBeforeTheFirstTrial) {
  const LineData data = MakeLineData(50, 50, 0.0, 3);
  CancelToken token;
  token.RequestCancel();
  const auto report = RANSAC<LineEstimator>(RANSACOptions()).Estimate(data.x, data.y, &token);
  EXPECT_FALSE(report.success);
  EXPECT_TRUE(report.canceled);
  EXPECT_EQ(report.num_trials, 0u);
  EXPECT_EQ(report.message, "canceled");
}

TEST(RANSAC, DynamicTrialCountStopsEarlyOnCleanData) {
  const LineData data = MakeLineData(100, 0, 0.0, 4);
  RANSACOptions options;
  options.max_error = 0.1;
  const auto report = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(report.success);
  // All inliers: k = log(1 - p) / log(1 - 1) -> 1 trial.
  EXPECT_EQ(report.num_trials, 1u);

  options.min_num_trials = 25;
  EXPECT_EQ(RANSAC<LineEstimator>(options).Estimate(data.x, data.y).num_trials, 25u);
}

TEST(RANSAC, MaxNumTrialsBoundsTheWork) {
  const LineData data = MakeLineData(10, 90, 0.0, 5);
  RANSACOptions options;
  options.max_error = 0.1;
  options.max_num_trials = 7;
  const auto report = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  EXPECT_EQ(report.num_trials, 7u);
}

TEST(RANSAC, TrialsNeverExceedTheNumberOfDistinctSamples) {
  // Two points have exactly one pair: one trial is all there is to do.
  const auto report = RANSAC<LineEstimator>(RANSACOptions()).Estimate({0.0, 1.0}, {1.0, 3.0});
  ASSERT_TRUE(report.success);
  EXPECT_EQ(report.num_trials, 1u);
  EXPECT_NEAR(report.model.slope, 2.0, 1e-12);
}

TEST(RANSAC, MSACScoresByTruncatedResiduals) {
  // Under a loose threshold every sample's line has all 40 points as inliers, so inlier
  // counting cannot tell them apart; MSAC keeps the line with the smallest residuals.
  const LineData data = MakeLineData(40, 0, 0.01, 6);
  RANSACOptions options;
  options.max_error = 5.0;
  const auto report =
      RANSAC<LineEstimator, MEstimatorSupportMeasurer>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(report.success);
  EXPECT_EQ(report.support.num_inliers, 40u);
  EXPECT_LT(report.support.score, 40 * 0.01);
  EXPECT_NEAR(report.model.slope, 2.0, 0.01);
}

}  // namespace
}  // namespace reconduit
