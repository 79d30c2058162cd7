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
  EXPECT_EQ(stats.num_conflicting_matches, 0u);
}

TEST(BuildTracks, RefusesTheMatchThatWouldHitAnImageTwice) {
  // 0:1 ~ 1:1 ~ 2:1 ~ 0:2 would put two keypoints of image 0 in one track. The weakest pair's
  // match (pair 1-2, one match) is the one refused.
  const std::vector<PairMatches> pairs = {
      {1, 2, {{1, 1}}},
      {0, 1, {{1, 1}, {5, 5}}},
      {0, 2, {{2, 1}, {3, 3}}},
  };
  TrackStatistics stats;
  const auto tracks = BuildTracks(pairs, 2, &stats);
  EXPECT_EQ(stats.num_conflicting_matches, 1u);
  ASSERT_EQ(tracks.size(), 4u);
  // By first observation: (0:1, 1:1), (0:2, 2:1), (0:3, 2:3), (0:5, 1:5).
  EXPECT_EQ(tracks[0].observations.size(), 2u);
  EXPECT_EQ(tracks[0].observations[1].image_id, 1);
  EXPECT_EQ(tracks[1].observations[0].keypoint, 2);
  EXPECT_EQ(tracks[1].observations[1].image_id, 2);
  EXPECT_EQ(tracks[1].observations[1].keypoint, 1);
  for (const Track& track : tracks) {
    for (std::size_t k = 1; k < track.observations.size(); ++k) {
      EXPECT_LT(track.observations[k - 1].image_id, track.observations[k].image_id);
    }
  }
}

TEST(BuildTracks, MinimumLength) {
  const std::vector<PairMatches> pairs = {{0, 1, {{0, 0}}}, {1, 2, {{0, 0}}}, {0, 1, {{4, 4}}}};
  EXPECT_EQ(BuildTracks(pairs, 3).size(), 1u);
  EXPECT_EQ(BuildTracks(pairs, 2).size(), 2u);
  EXPECT_TRUE(BuildTracks({}, 2).empty());
}

}  // namespace
}  // namespace reconduit
