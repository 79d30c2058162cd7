#include "core/pipeline/stages/weak_pairs.h"

#include "core/util/logging.h"

#include <map>
#include <sstream>

namespace reconduit {
namespace {

bool Strong(const PairStrength& p, const WeakPairOptions& options) {
  return p.usable && p.inliers >= options.strong_pair_inliers;
}

}  // namespace

bool WeakPairOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (strong_pair_inliers < 8) {
    m << "strong_pair_inliers must be at least 8, got " << strong_pair_inliers;
  } else if (min_strong_pairs < 1) {
    m << "min_strong_pairs must be at least 1, got " << min_strong_pairs;
  } else if (!(retry_ratio > 0 && retry_ratio <= 1)) {
    m << "retry_ratio must be in (0, 1], got " << retry_ratio;
  } else if (!(min_inlier_share >= 0 && min_inlier_share <= 1)) {
    m << "min_inlier_share must be in [0, 1], got " << min_inlier_share;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::vector<std::size_t> PairsToRetry(const std::vector<PairStrength>& pairs,
                                      const WeakPairOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  std::map<int, int> strong;  // Photo -> strong pairs.
  for (const PairStrength& p : pairs) {
    if (!Strong(p, options)) continue;
    ++strong[p.image1];
    ++strong[p.image2];
  }
  std::vector<std::size_t> retry;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const PairStrength& p = pairs[k];
    if (!Strong(p, options) && (strong[p.image1] < options.min_strong_pairs ||
                                strong[p.image2] < options.min_strong_pairs)) {
      retry.push_back(k);
    }
  }
  return retry;
}

bool KeepRetry(bool fundamental, int inliers_F, int putative, const WeakPairOptions& options) {
  return fundamental && inliers_F >= options.strong_pair_inliers &&
         inliers_F >= options.min_inlier_share * putative;
}

}  // namespace reconduit
