// Affine-adapted features for photos far apart (issue 13, "wide baselines").
//
// SIFT is invariant to scale and rotation, not to the tilt a surface shows when the camera
// moves around it: beyond ~40-50 deg the same patch is squeezed along one direction and its
// descriptor no longer matches. ASIFT (Morel & Yu 2009, "ASIFT: A New Framework for Fully
// Affine Invariant Image Comparison") simulates the tilts instead: it runs SIFT on copies of
// the photo squeezed by t = sqrt(2)^k (k = 0 .. max_tilt) along directions 72/t deg apart,
// and maps the keypoints back. OpenCV's cv::AffineFeature does that with any detector; we
// give it SIFT at our contrast threshold and turn the descriptors into quantised RootSIFT like
// core/feature/sift.h, so that core/feature/matcher.h matches them unchanged.
//
// Measured on templeSparseRing's photos (640 x 480, ~1,300 SIFT features each): neighbours
// 55 deg apart had 10 RANSAC inliers of F from SIFT (5 of them true), 56 from ASIFT (54 true);
// 73 deg apart 16 (11) against 91 (87); 48 deg 62 against 279. It costs: ~15,000-20,000
// keypoints and 1-2 s a 640 x 480 photo on one core, so the matching stage computes them only
// for the photos it has to try harder on (matching_stage.cc).
#ifndef RECONDUIT_CORE_FEATURE_AFFINE_FEATURES_H_
#define RECONDUIT_CORE_FEATURE_AFFINE_FEATURES_H_

#include "core/feature/features.h"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace reconduit {

struct AffineFeatureOptions {
  // Features are detected on a copy whose longer side is at most this many pixels; keypoints
  // are reported in original-image pixels. A 1024 px copy holds ~3.4x the pixels of a
  // 640 x 480 photo (~5 s). [64, 20000]
  int max_image_side = 1024;
  // Tilts simulated: sqrt(2)^0 .. sqrt(2)^(max_tilt - 1) (OpenCV's convention: 5 reaches
  // t = 4, views up to ~75 deg from the surface's normal). [1, 8]
  int max_tilt = 5;
  // SIFT's DoG contrast threshold (OpenCV's convention; sift.h). (0, 1]
  double contrast_threshold = 0.02;
  // Keypoints closer than this to a stronger one are dropped (pixels of the original): the
  // same corner found again at several tilts would otherwise fail the ratio test against its
  // own copies. [0, 10]
  double duplicate_radius_px = 1.0;

  bool Check(std::string* error) const;
};

// Affine-adapted SIFT of `image` (8-bit, grey or BGR), a copy of a photo of `original_size`
// pixels (equal or smaller, same aspect). Strongest first. Deterministic for the same input.
FeatureSet ExtractAffineFeatures(const cv::Mat& image,
                                 const AffineFeatureOptions& options,
                                 cv::Size original_size);

// Indices (original order) of the keypoints that survive a duplicate radius: each keypoint in
// order of decreasing response is kept unless a kept one lies within `radius` pixels.
std::vector<int> DropDuplicateKeypoints(const std::vector<Keypoint>& keypoints, double radius);

// Gives each of `extra` an index among a photo's keypoints `base` extended by `appended`: a
// keypoint within `radius` pixels of one of `base` takes the nearest one's index (a track
// through it then meets the photo's other matches); any other is appended to *appended
// (same order) and takes base.size() + its position there.
std::vector<int> MergeKeypoints(const std::vector<Keypoint>& base,
                                const std::vector<Keypoint>& extra,
                                double radius,
                                std::vector<Keypoint>* appended);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_FEATURE_AFFINE_FEATURES_H_
