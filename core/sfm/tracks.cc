#include "core/sfm/tracks.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <unordered_map>

namespace reconduit {
namespace {

class UnionFind {
 public:
  int Add() {
    parent_.push_back(static_cast<int>(parent_.size()));
    rank_.push_back(0);
    return parent_.back();
  }
  int Find(int x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];  // Path halving.
      x = parent_[x];
    }
    return x;
  }
  void Union(int a, int b) {
    a = Find(a);
    b = Find(b);
    if (a == b) return;
    if (rank_[a] < rank_[b]) std::swap(a, b);
    parent_[b] = a;
    if (rank_[a] == rank_[b]) ++rank_[a];
  }

 private:
  std::vector<int> parent_;
  std::vector<int> rank_;
};

std::uint64_t Key(int image, int keypoint) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(image)) << 32) |
         static_cast<std::uint32_t>(keypoint);
}

}  // namespace

std::vector<Track> BuildTracks(const std::vector<PairMatches>& pairs,
                               std::size_t min_length,
                               TrackStatistics* statistics) {
  UnionFind sets;
  std::unordered_map<std::uint64_t, int> node_of;
  std::vector<Observation> observation_of;
  auto node = [&](int image, int keypoint) {
    const auto [it, inserted] = node_of.try_emplace(Key(image, keypoint), 0);
    if (inserted) {
      it->second = sets.Add();
      observation_of.push_back({image, keypoint});
    }
    return it->second;
  };
  for (const PairMatches& pair : pairs) {
    for (const FeatureMatch& m : pair.matches) {
      sets.Union(node(pair.image1, m.index1), node(pair.image2, m.index2));
    }
  }

  std::unordered_map<int, std::vector<Observation>> components;
  for (int n = 0; n < static_cast<int>(observation_of.size()); ++n) {
    components[sets.Find(n)].push_back(observation_of[n]);
  }
  std::vector<Track> tracks;
  TrackStatistics stats;
  for (auto& [root, observations] : components) {
    std::sort(observations.begin(), observations.end(),
              [](const Observation& a, const Observation& b) {
                return a.image_id != b.image_id ? a.image_id < b.image_id : a.keypoint < b.keypoint;
              });
    const bool consistent = std::adjacent_find(observations.begin(), observations.end(),
                                               [](const Observation& a, const Observation& b) {
                                                 return a.image_id == b.image_id;
                                               }) == observations.end();
    if (!consistent) {
      ++stats.num_inconsistent;
      continue;
    }
    if (observations.size() < min_length) continue;
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
