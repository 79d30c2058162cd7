// Feature tracks: the sets of keypoints, one per image, that show the same scene point.
//
// Tracks are the connected components of the graph whose nodes are (image, keypoint) and whose
// edges are the verified pairwise matches (union-find, as in Bundler and OpenMVG). A component
// that contains two different keypoints of one image is inconsistent — some match in it is
// wrong, and we cannot tell which — so it is dropped, as Moulon & Monasse 2012 ("Unordered
// feature tracking made fast and easy") recommend.
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
  std::size_t num_inconsistent = 0;  // Dropped: two keypoints of one image.
  std::size_t num_observations = 0;
};

// Builds tracks of at least `min_length` images.
std::vector<Track> BuildTracks(const std::vector<PairMatches>& pairs,
                               std::size_t min_length = 2,
                               TrackStatistics* statistics = nullptr);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_TRACKS_H_
