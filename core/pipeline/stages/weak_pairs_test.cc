#include "core/pipeline/stages/weak_pairs.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

TEST(WeakPairOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(WeakPairOptions().Check(&error)) << error;
  WeakPairOptions bad;
  bad.retry_ratio = 1.5;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("retry_ratio"), std::string::npos);
  EXPECT_THROW(PairsToRetry({}, bad), CheckError);
}

// A chain 0-1-2-3 whose link 1-2 is weak: photos 1 and 2 have one strong pair each, so the
// weak link and the other weak pairs of 1 and 2 are retried; the weak pair 0-3 of two photos
// that each have two strong pairs (0-1, 0-4 and 3-2, 3-4) is not.
TEST(PairsToRetry, OnlyPhotosWithTooFewStrongPairs) {
  const std::vector<PairStrength> pairs = {
      {0, 1, 120, true},  // 0: strong
      {1, 2, 24, true},   // 1: the weak link
      {2, 3, 80, true},   // 2: strong
      {0, 4, 60, true},   // 3: strong
      {3, 4, 45, true},   // 4: strong
      {0, 3, 12, false},  // 5: weak, between well-connected photos
      {1, 3, 15, true},   // 6: weak, photo 1 has one strong pair
      {4, 2, 29, true},   // 7: weak (29 < 30), photo 2 has one strong pair
  };
  EXPECT_EQ(PairsToRetry(pairs, WeakPairOptions()), (std::vector<std::size_t>{1, 6, 7}));
  WeakPairOptions one;
  one.min_strong_pairs = 1;
  EXPECT_TRUE(PairsToRetry(pairs, one).empty()) << "every photo has a strong pair";
}

TEST(PairsToRetry, AStrongPairWithoutMatchesIsWeak) {
  // Inliers counted but no verified matches kept (a failed verification): not strong.
  const std::vector<PairStrength> pairs = {{0, 1, 40, false}, {1, 2, 40, true}};
  EXPECT_EQ(PairsToRetry(pairs, WeakPairOptions()), (std::vector<std::size_t>{0}));
}

TEST(KeepRetry, NumberAndShareOfInliers) {
  const WeakPairOptions options;
  EXPECT_TRUE(KeepRetry(true, 54, 153, options)) << "true neighbours 42 deg apart: 35 %";
  EXPECT_FALSE(KeepRetry(true, 30, 152, options)) << "a false F on the far side: 20 %";
  EXPECT_FALSE(KeepRetry(true, 25, 60, options)) << "too few inliers, whatever the share";
  EXPECT_FALSE(KeepRetry(false, 54, 153, options)) << "a homography is no new link";
  EXPECT_TRUE(KeepRetry(true, 30, 120, options)) << "exactly at both limits";
}

}  // namespace
}  // namespace reconduit
