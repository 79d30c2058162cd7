// SIFT detection with RootSIFT descriptors, spread over the whole image.
//
// OpenCV's SIFT (Lowe 2004) detects candidates on a working copy of the image no larger than
// `max_image_side`. Keeping only the strongest responses piles features onto the most
// textured region and leaves the rest of the image empty, which starves pose estimation and
// self-calibration of the image borders. Like ARC3D (Vergauwen, "Harnessing
// Structure-and-Motion", §3.2.1) we keep the strongest (1 - spread_fraction) of the budget
// and fill the rest with the best remaining candidates cell by cell over a regular grid.
#ifndef RECONDUIT_CORE_FEATURE_SIFT_H_
#define RECONDUIT_CORE_FEATURE_SIFT_H_

#include "core/feature/features.h"
#include "core/options/feature_limits.h"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace reconduit {

struct SiftOptions {
  // Features are detected on a copy whose longer side is at most this many pixels (INTER_AREA
  // downscaling); keypoints are reported in original-image pixels. [64, 20000]
  int max_image_side = 3200;
  // At most this many features per image. [kMinMaxFeatures, kMaxMaxFeatures], the range of
  // the max_features option (core/options/feature_limits.h).
  int max_features = kDefaultMaxFeatures;
  // Share of max_features chosen per grid cell rather than by global strength. [0, 1]
  double spread_fraction = 0.3;
  // Grid cells along the image's longer side for the spread (square cells). [1, 64]
  int grid_cells = 8;
  // DoG contrast threshold in OpenCV's convention (it divides by octave_layers); lower finds
  // more candidates in low-contrast areas. COLMAP's default peak threshold 0.02/3 corresponds
  // to 0.02 here. (0, 1]
  double contrast_threshold = 0.02;
  // Edge-response threshold (Lowe's r). [1, 100]
  double edge_threshold = 10.0;
  // Scale levels per octave. [1, 8]
  int octave_layers = 3;

  bool Check(std::string* error) const;
};

// Detects and describes features in `image` (8-bit, grey or BGR, original resolution).
// Deterministic for the same input.
FeatureSet ExtractSiftFeatures(const cv::Mat& image, const SiftOptions& options);
// The same for `image`, a downscaled copy of a photo of `original_size` pixels (read at its
// working size): keypoints and image size are reported in the original's pixels.
FeatureSet ExtractSiftFeatures(const cv::Mat& image,
                               const SiftOptions& options,
                               cv::Size original_size);

// Chooses at most `max_features` of `candidates` (any order): the strongest
// (1 - spread_fraction) by response, then round-robin the best remaining one per grid cell.
// Returns indices into `candidates`, strongest-first within each part. Exposed for tests.
std::vector<int> SelectSpreadKeypoints(const std::vector<cv::KeyPoint>& candidates,
                                       int image_width,
                                       int image_height,
                                       int max_features,
                                       double spread_fraction,
                                       int grid_cells);

// Turns OpenCV SIFT descriptors (float rows of 128) into quantised RootSIFT (CV_8U rows).
cv::Mat ToRootSiftBytes(const cv::Mat& sift_descriptors);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_FEATURE_SIFT_H_
