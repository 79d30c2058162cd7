#include "core/mvs/cloud_distance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace reconduit {
namespace {

TEST(CloudDistanceTest, MatchesBruteForceWithinTheRadiusAndInfinityBeyond) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Eigen::Vector3f> cloud(2000);
  for (auto& p : cloud) p = {u(rng), u(rng), 10.0f + u(rng)};
  std::vector<Eigen::Vector3d> queries(300);
  for (auto& q : queries) q = {1.3 * u(rng), 1.3 * u(rng), 10.0 + 1.3 * u(rng)};
  const double radius = 0.08;
  const std::vector<double> got = NearestDistancesWithin(cloud, queries, radius);
  ASSERT_EQ(got.size(), queries.size());
  int within = 0, beyond = 0;
  for (std::size_t q = 0; q < queries.size(); ++q) {
    double best = INFINITY;
    for (const auto& p : cloud) best = std::min(best, (p.cast<double>() - queries[q]).norm());
    if (best <= radius) {
      EXPECT_NEAR(got[q], best, 1e-12);
      ++within;
    } else {
      EXPECT_TRUE(std::isinf(got[q])) << best;
      ++beyond;
    }
  }
  EXPECT_GT(within, 50);
  EXPECT_GT(beyond, 10);
}

TEST(CloudDistanceTest, EmptyCloudAndMedian) {
  EXPECT_TRUE(std::isinf(NearestDistancesWithin({}, {{0, 0, 0}}, 1.0)[0]));
  EXPECT_DOUBLE_EQ(Median({3, 1, 2}), 2.0);
  EXPECT_TRUE(std::isinf(Median({1, INFINITY, INFINITY})));
  EXPECT_TRUE(std::isnan(Median({})));
}

}  // namespace
}  // namespace reconduit
