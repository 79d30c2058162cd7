#include "core/sfm/tracks.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

TEST(BuildTracks, ChainsMatchesAcrossPairs) {
  // Keypoint 5 of image 0 ~ 7 of image 1 ~ 2 of image 2, seen through two pairs.
  const std::vector<PairMatches> pairs = {
      {0, 1, {{5, 7}, {1, 1}}},
      {1, 2, {{7, 2}}},
  };
  TrackStatistics stats;
  const auto tracks = BuildTracks(pairs, 2, &stats);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0].observations.size(), 2u);  // (0,1)-(1,1)
  EXPECT_EQ(tracks[0].observations[0].keypoint, 1);
  ASSERT_EQ(tracks[1].observations.size(), 3u);
  EXPECT_EQ(tracks[1].observations[2].image_id, 2);
  EXPECT_EQ(tracks[1].observations[2].keypoint, 2);
  EXPECT_EQ(stats.num_observations, 5u);
  EXPECT_EQ(stats.num_inconsistent, 0u);
}

TEST(BuildTracks, DropsTracksThatHitAnImageTwice) {
  // 0:1 ~ 1:1 ~ 2:1 ~ 0:2 — two keypoints of image 0 in one component.
  const std::vector<PairMatches> pairs = {
      {0, 1, {{1, 1}}},
      {1, 2, {{1, 1}}},
      {0, 2, {{2, 1}, {3, 3}}},
  };
  TrackStatistics stats;
  const auto tracks = BuildTracks(pairs, 2, &stats);
  ASSERT_EQ(tracks.size(), 1u);
  EXPECT_EQ(tracks[0].observations[0].keypoint, 3);
  EXPECT_EQ(stats.num_inconsistent, 1u);
}

TEST(BuildTracks, MinimumLength) {
  const std::vector<PairMatches> pairs = {{0, 1, {{0, 0}}}, {1, 2, {{0, 0}}}, {0, 1, {{4, 4}}}};
  EXPECT_EQ(BuildTracks(pairs, 3).size(), 1u);
  EXPECT_EQ(BuildTracks(pairs, 2).size(), 2u);
  EXPECT_TRUE(BuildTracks({}, 2).empty());
}

}  // namespace
}  // namespace reconduit
