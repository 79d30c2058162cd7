#include "core/optim/loransac.h"

#include "core/optim/line_estimator_test_util.h"
#include "core/optim/ransac.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace reconduit {
namespace {

using testing_util::Line;
using testing_util::LineEstimator;
using testing_util::RefiningLineEstimator;

struct NoisyLine {
  std::vector<double> x, y;
  std::vector<char> is_inlier;
};

// Inliers on y = -0.5x + 3 with Gaussian noise; outliers 2-20 away, alternating.
NoisyLine MakeData(int n, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-10.0, 10.0);
  std::uniform_real_distribution<double> uoff(2.0, 20.0);
  std::normal_distribution<double> gauss(0.0, noise);
  NoisyLine data;
  for (int i = 0; i < n; ++i) {
    const double x = ux(rng);
    const bool inlier = i % 2 == 0;
    data.x.push_back(x);
    data.y.push_back(-0.5 * x + 3.0 + (inlier ? gauss(rng) : uoff(rng) * (i % 4 == 1 ? 1 : -1)));
    data.is_inlier.push_back(inlier ? 1 : 0);
  }
  return data;
}

double LineError(const Line& line) {
  return std::abs(line.slope + 0.5) * 10.0 + std::abs(line.offset - 3.0);
}

TEST(LORANSAC, RecoversLineAndExactInlierSetWithHalfOutliers) {
  const NoisyLine data = MakeData(200, 0.05, 7);
  RANSACOptions options;
  options.max_error = 1.0;  // 20 sigma: no inlier is lost, no outlier (>= 2 away) accepted.
  const auto report = LORANSAC<LineEstimator, LineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(report.success) << report.message;
  EXPECT_EQ(report.inlier_mask, data.is_inlier);
  EXPECT_EQ(report.support.num_inliers, 100u);
  EXPECT_NEAR(report.model.slope, -0.5, 0.01);
  EXPECT_NEAR(report.model.offset, 3.0, 0.02);
}

TEST(LORANSAC, LocalOptimisationFitsAllInliersBetterThanAMinimalSample) {
  const NoisyLine data = MakeData(400, 0.2, 8);
  RANSACOptions options;
  options.max_error = 1.0;
  options.random_seed = 3;
  const auto plain = RANSAC<LineEstimator>(options).Estimate(data.x, data.y);
  const auto lo = LORANSAC<LineEstimator, LineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(plain.success);
  ASSERT_TRUE(lo.success);
  // The LO model is the least-squares fit to ~200 inliers: its error is ~sigma/sqrt(200).
  EXPECT_LT(LineError(lo.model), 0.1);
  EXPECT_LE(LineError(lo.model), LineError(plain.model));
  EXPECT_GE(lo.support.num_inliers, plain.support.num_inliers);
}

TEST(LORANSAC, UsesRefineWhenTheLocalEstimatorHasIt) {
  static_assert(kHasRefine<RefiningLineEstimator>);
  static_assert(!kHasRefine<LineEstimator>);
  const NoisyLine data = MakeData(100, 0.05, 9);
  RANSACOptions options;
  options.max_error = 1.0;
  RefiningLineEstimator::num_refine_calls = 0;
  const auto report =
      LORANSAC<LineEstimator, RefiningLineEstimator>(options).Estimate(data.x, data.y);
  ASSERT_TRUE(report.success);
  EXPECT_GT(RefiningLineEstimator::num_refine_calls, 0);
  EXPECT_EQ(report.inlier_mask, data.is_inlier);
}

TEST(LORANSAC, ReproducibleWithASeed) {
  const NoisyLine data = MakeData(100, 0.1, 10);
  RANSACOptions options;
  options.max_error = 1.0;
  options.random_seed = 12345;
  const LORANSAC<LineEstimator, LineEstimator, MEstimatorSupportMeasurer> ransac(options);
  const auto a = ransac.Estimate(data.x, data.y);
  const auto b = ransac.Estimate(data.x, data.y);
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.num_trials, b.num_trials);
  EXPECT_EQ(a.model.slope, b.model.slope);
  EXPECT_EQ(a.support.score, b.support.score);
  EXPECT_EQ(a.inlier_mask, b.inlier_mask);
}

TEST(LORANSAC, DegenerateAndTooFewPointsFailWithMessage) {
  const LORANSAC<LineEstimator, RefiningLineEstimator> ransac{RANSACOptions()};
  const auto too_few = ransac.Estimate({1.0}, {1.0});
  EXPECT_FALSE(too_few.success);
  EXPECT_FALSE(too_few.message.empty());
  const auto degenerate = ransac.Estimate({1.0, 1.0, 1.0, 1.0}, {0.0, 1.0, 2.0, 3.0});
  EXPECT_FALSE(degenerate.success);
  EXPECT_FALSE(degenerate.message.empty());
}

}  // namespace
}  // namespace reconduit
