#include "core/sfm/tracks.h"

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <numeric>
#include <unordered_map>

namespace reconduit {
namespace {

// Union-find whose sets remember the images they hold, so that a union which would put two
// keypoints of one image into a set can be refused.
class TrackSets {
 public:
  int Add(int image) {
    parent_.push_back(static_cast<int>(parent_.size()));
    images_.push_back({image});
    return parent_.back();
  }
  int Find(int x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];  // Path halving.
      x = parent_[x];
    }
    return x;
  }
  // False (and nothing changes) when the two sets share an image.
  bool Union(int a, int b) {
    a = Find(a);
    b = Find(b);
    if (a == b) return true;
    std::vector<int>& ia = images_[a];
    std::vector<int>& ib = images_[b];
    std::vector<int> merged;
    merged.reserve(ia.size() + ib.size());
    std::merge(ia.begin(), ia.end(), ib.begin(), ib.end(), std::back_inserter(merged));
    if (std::adjacent_find(merged.begin(), merged.end()) != merged.end()) return false;
    if (ia.size() < ib.size()) std::swap(a, b);  // Union by size.
    parent_[b] = a;
    images_[a] = std::move(merged);
    images_[b] = {};
    return true;
  }

 private:
  std::vector<int> parent_;
  std::vector<std::vector<int>> images_;  // Sorted image ids of each root's set.
};

std::uint64_t Key(int image, int keypoint) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(image)) << 32) |
         static_cast<std::uint32_t>(keypoint);
}

}  // namespace

std::vector<Track> BuildTracks(const std::vector<PairMatches>& pairs,
                               std::size_t min_length,
                               TrackStatistics* statistics) {
  TrackSets sets;
  std::unordered_map<std::uint64_t, int> node_of;
  std::vector<Observation> observation_of;
  auto node = [&](int image, int keypoint) {
    const auto [it, inserted] = node_of.try_emplace(Key(image, keypoint), 0);
    if (inserted) {
      it->second = sets.Add(image);
      observation_of.push_back({image, keypoint});
    }
    return it->second;
  };
  TrackStatistics stats;
  // Strongest pairs first: when matches conflict, those of a pair with more verified matches
  // (the more reliable geometry) are kept.
  std::vector<const PairMatches*> order;
  for (const PairMatches& pair : pairs) order.push_back(&pair);
  std::stable_sort(order.begin(), order.end(), [](const PairMatches* a, const PairMatches* b) {
    return a->matches.size() > b->matches.size();
  });
  for (const PairMatches* pair : order) {
    for (const FeatureMatch& m : pair->matches) {
      if (!sets.Union(node(pair->image1, m.index1), node(pair->image2, m.index2))) {
        ++stats.num_conflicting_matches;
      }
    }
  }

  std::unordered_map<int, std::vector<Observation>> components;
  for (int n = 0; n < static_cast<int>(observation_of.size()); ++n) {
    components[sets.Find(n)].push_back(observation_of[n]);
  }
  std::vector<Track> tracks;
  for (auto& [root, observations] : components) {
    if (observations.size() < min_length) continue;
    std::sort(observations.begin(), observations.end(),
              [](const Observation& a, const Observation& b) { return a.image_id < b.image_id; });
    stats.num_observations += observations.size();
    tracks.push_back({std::move(observations)});
  }
  // Deterministic order: by first observation.
  std::sort(tracks.begin(), tracks.end(), [](const Track& a, const Track& b) {
    const Observation& x = a.observations.front();
    const Observation& y = b.observations.front();
    return x.image_id != y.image_id ? x.image_id < y.image_id : x.keypoint < y.keypoint;
  });
  stats.num_tracks = tracks.size();
  if (statistics != nullptr) *statistics = stats;
  return tracks;
}

}  // namespace reconduit
