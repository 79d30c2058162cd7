// Feature tracks: the sets of keypoints, one per image, that show the same scene point.
//
// Tracks are the connected components of the graph whose nodes are (image, keypoint) and whose
// edges are the verified pairwise matches (union-find, as in Bundler and OpenMVG). A track must
// not hold two keypoints of one image: some match that joins them is wrong. Moulon & Monasse
// 2012 ("Unordered feature tracking made fast and easy") drop such components whole; with
// guided matching (many more matches, so more chance meetings) that lost more than half of
// fountain-P11's points. Instead, matches are merged pair by pair, strongest pair first, and
// a match whose union would put two keypoints of one image together is refused: the track
// keeps the observations the stronger pairs agreed on, and the refused match is counted.
#ifndef RECONDUIT_CORE_SFM_TRACKS_H_
#define RECONDUIT_CORE_SFM_TRACKS_H_

#include "core/feature/matcher.h"
#include "core/scene/reconstruction.h"

#include <cstddef>
#include <vector>

namespace reconduit {

// Verified matches between two images (image ids are input indices).
struct PairMatches {
  int image1 = kInvalidId;
  int image2 = kInvalidId;
  std::vector<FeatureMatch> matches;
};

struct Track {
  std::vector<Observation> observations;  // Sorted by image id, one per image.
};

struct TrackStatistics {
  std::size_t num_tracks = 0;
  // Matches refused because they would join two keypoints of one image in a track.
  std::size_t num_conflicting_matches = 0;
  std::size_t num_observations = 0;
};

// Builds tracks of at least `min_length` images.
std::vector<Track> BuildTracks(const std::vector<PairMatches>& pairs,
                               std::size_t min_length = 2,
                               TrackStatistics* statistics = nullptr);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_TRACKS_H_
