// Exhaustive descriptor matching: exact nearest neighbours, Lowe's ratio test, mutual check.
//
// All pairwise descriptor distances between two images come from one matrix product
// (|a - b|² = |a|² + |b|² - 2 a·b), computed in row blocks with OpenBLAS's sgemm so memory
// stays bounded (block x n floats) and every core instruction set is used at run time.
// This is what COLMAP's CPU matcher does too; it is exact (no approximate-search misses),
// deterministic, and for the few thousand features per image we keep it beats approximate
// trees on 2 cores. Image pairs, not rows, are the unit of parallelism: sgemm runs
// single-threaded here.
#ifndef RECONDUIT_CORE_FEATURE_MATCHER_H_
#define RECONDUIT_CORE_FEATURE_MATCHER_H_

#include "core/feature/features.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace reconduit {

struct FeatureMatch {
  int index1 = -1;  // Keypoint index in the first image.
  int index2 = -1;  // Keypoint index in the second image.
};

struct MatchingOptions {
  // Lowe's ratio: best distance / second-best distance must be below this. (0, 1]
  double max_ratio = 0.8;
  // Largest descriptor distance accepted, for unit-norm RootSIFT (0 = identical, 2 = opposite;
  // COLMAP uses 0.7). (0, 2]
  double max_distance = 0.7;
  // Keep a match only if each feature is the other's nearest neighbour.
  bool cross_check = true;

  bool Check(std::string* error) const;
};

// Descriptors as unit-norm floats, rows = features, ready for the matrix product.
using DescriptorMatrix = Eigen::Matrix<float, Eigen::Dynamic, 128, Eigen::RowMajor>;
DescriptorMatrix ToDescriptorMatrix(const FeatureSet& features);

// Matches every descriptor of `descriptors1` against `descriptors2`. Sorted by index1.
std::vector<FeatureMatch> MatchDescriptors(const DescriptorMatrix& descriptors1,
                                           const DescriptorMatrix& descriptors2,
                                           const MatchingOptions& options);

// Guided matching along epipolar lines (Hartley & Zisserman, "Multiple View Geometry", 2nd ed.,
// §11.6, the final step of automatic F estimation): once a pair's fundamental matrix is
// known, every feature of the first image is compared only with the features of the second
// image that lie near its epipolar line. With a few dozen candidates instead of thousands, a
// repeated texture elsewhere in the image no longer fails the ratio test, so matches the
// unguided pass had to drop come back, each consistent with F by construction.
struct GuidedMatchingOptions {
  // Candidates: Sampson distance of the pair (x1, x2) under F below this, pixels. Tighter
  // than a RANSAC band: these matches get no further consensus check. (0, ...)
  double max_sampson_px = 1.5;
  // Ratio test among the candidates only. (0, 1]
  double max_ratio = 0.8;
  // As in MatchingOptions. (0, 2]
  double max_distance = 0.7;
  // Each feature must be the other's best candidate.
  bool cross_check = true;

  bool Check(std::string* error) const;
};

// Matches `descriptors1` against `descriptors2` among epipolar candidates. Keypoints are in
// pixels (rows of the descriptor matrices), F maps image-1 points to image-2 lines
// (x2ᵀ F x1 = 0). Sorted by index1.
std::vector<FeatureMatch> GuidedMatchDescriptors(const DescriptorMatrix& descriptors1,
                                                 const DescriptorMatrix& descriptors2,
                                                 const std::vector<Eigen::Vector2d>& keypoints1,
                                                 const std::vector<Eigen::Vector2d>& keypoints2,
                                                 const Eigen::Matrix3d& F,
                                                 const GuidedMatchingOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_FEATURE_MATCHER_H_
