// Trying harder on weak pairs (issue 13): photos far apart share few matches because the
// true match's descriptor has changed with the viewpoint and often fails Lowe's ratio test
// against a look-alike. The matching stage verifies such pairs again at a looser ratio, but
// only the weak pairs of photos that have too few strong partners to sit inside a chain:
// photos with enough strong pairs are left as they are, so well-connected sets do not change
// (on the full templeSparseRing, retrying all of its 5 weak pairs moved the focal by 0.3 %,
// about its standard deviation, past the set's 0.3 % target).
//
// A retry is kept only when its fundamental matrix has enough inliers, both in number and as a
// share of the putative matches: at the looser ratio a false F easily finds 20-30 inliers
// among 110-170 putative matches, 15-22 % of them (templeSparseRing every second photo: 13
// pairs 120-165 deg apart, the temple's other side), while the true neighbours 42 deg apart
// reach 54 of 153, 35 % (24 inliers at ratio 0.8).
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_WEAK_PAIRS_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_WEAK_PAIRS_H_

#include <cstddef>
#include <string>
#include <vector>

namespace reconduit {

struct WeakPairOptions {
  // A pair is strong from this many RANSAC inliers of its two-view model. [8, ...]
  int strong_pair_inliers = 30;
  // A photo with fewer strong pairs has its weak pairs verified again. [1, ...]
  int min_strong_pairs = 2;
  // Lowe's ratio of the second verification. (0, 1]
  double retry_ratio = 0.9;
  // A retry is kept with at least strong_pair_inliers inliers of its F, and this share of its
  // putative matches. [0, 1]
  double min_inlier_share = 0.25;

  bool Check(std::string* error) const;
};

// One verified pair as the first pass left it.
struct PairStrength {
  int image1 = -1;
  int image2 = -1;
  int inliers = 0;      // RANSAC inliers of the chosen model (guided matches not counted).
  bool usable = false;  // The pair has verified matches.
};

// The weak pairs (indices into `pairs`) one of whose photos has fewer than min_strong_pairs
// strong pairs. Throws on invalid options.
std::vector<std::size_t> PairsToRetry(const std::vector<PairStrength>& pairs,
                                      const WeakPairOptions& options);

// Whether a second verification is kept: a fundamental matrix with enough inliers, in number
// and as a share of the putative matches.
bool KeepRetry(bool fundamental, int inliers_F, int putative, const WeakPairOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_WEAK_PAIRS_H_
