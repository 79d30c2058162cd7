#include "core/optim/random_sampler.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <limits>
#include <set>
#include <vector>

namespace reconduit {
namespace {

TEST(RandomSampler, DrawsDistinctIndicesInRangeAndCoversAll) {
  RandomSampler sampler(5, /*seed=*/7);
  sampler.Initialize(20);
  std::vector<int> counts(20, 0);
  std::vector<std::size_t> sample;
  for (int trial = 0; trial < 2000; ++trial) {
    sampler.Sample(&sample);
    ASSERT_EQ(sample.size(), 5u);
    const std::set<std::size_t> unique(sample.begin(), sample.end());
    EXPECT_EQ(unique.size(), 5u);
    for (const std::size_t i : sample) {
      ASSERT_LT(i, 20u);
      ++counts[i];
    }
  }
  // Uniform: each index is drawn 2000 * 5 / 20 = 500 times on average.
  for (const int c : counts) {
    EXPECT_GT(c, 400);
    EXPECT_LT(c, 600);
  }
}

TEST(RandomSampler, SameSeedSameSequence) {
  RandomSampler a(3, 99), b(3, 99), c(3, 100);
  a.Initialize(50);
  b.Initialize(50);
  c.Initialize(50);
  std::vector<std::size_t> sa, sb, sc;
  bool any_different = false;
  for (int i = 0; i < 20; ++i) {
    a.Sample(&sa);
    b.Sample(&sb);
    c.Sample(&sc);
    EXPECT_EQ(sa, sb);
    any_different |= sa != sc;
  }
  EXPECT_TRUE(any_different);
}

TEST(RandomSampler, MaxNumSamplesIsTheBinomialCoefficient) {
  RandomSampler sampler(7, 1);
  sampler.Initialize(7);
  EXPECT_EQ(sampler.MaxNumSamples(), 1u);
  RandomSampler three(3, 1);
  three.Initialize(10);
  EXPECT_EQ(three.MaxNumSamples(), 120u);
  RandomSampler big(8, 1);
  big.Initialize(1000000);
  EXPECT_EQ(big.MaxNumSamples(), std::numeric_limits<std::size_t>::max());
}

TEST(RandomSampler, PreconditionsThrow) {
  EXPECT_THROW(RandomSampler(0, 1), CheckError);
  RandomSampler sampler(4, 1);
  EXPECT_THROW(sampler.Initialize(3), CheckError);
  std::vector<std::size_t> sample;
  EXPECT_THROW(sampler.Sample(&sample), CheckError);
}

}  // namespace
}  // namespace reconduit
