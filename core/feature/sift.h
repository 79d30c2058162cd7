// SIFT detection with RootSIFT descriptors, spread over the whole image.
//
// OpenCV's SIFT (Lowe 2004) detects candidates on a working copy of the image no larger than
// `max_image_side`. Keeping only the strongest responses piles features onto the most
// textured region and leaves the rest of the image empty, which starves pose estimation and
// self-calibration of the image borders. Like ARC3D (Vergauwen, "Harnessing
// Structure-and-Motion", §3.2.1) we keep the strongest (1 - spread_fraction) of the budget
// and fill the rest with the best remaining candidates cell by cell over a regular grid.
//
// Memory. OpenCV keeps the whole Gaussian and DoG pyramids of the doubled image in floats:
// about 260 bytes per working pixel, 2.7 GB for a 3200 x 3200 working copy. A working copy
// above `max_tile_pixels` is described in pieces instead, so that a photo's peak stays near
// 260 * max_tile_pixels bytes whatever its size:
//  - the two finest octaves (OpenCV's -1 and 0, scales up to about 7 working pixels) on
//    overlapping tiles, each keeping the keypoints that fall in its own part; the margin
//    (kSiftTileMargin) covers the blur and the descriptor window of those scales, so a tile
//    finds what the whole image would up to rounding;
//  - every coarser octave on a copy downscaled 4x: the doubled first octave of that copy has
//    the resolution and blur of the working copy's octave 1 (Lowe's pyramid halves the image
//    per octave), so running SIFT on it gives octaves 1, 2, ... of the working copy; the copy
//    is itself tiled when still too large.
// sift_test checks the pieces against the whole image's keypoints and that the peak drops.
#ifndef RECONDUIT_CORE_FEATURE_SIFT_H_
#define RECONDUIT_CORE_FEATURE_SIFT_H_

#include "core/feature/features.h"
#include "core/options/feature_limits.h"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace reconduit {

// Tiles overlap by this many pixels on each side (of the image they cut).
inline constexpr int kSiftTileMargin = 112;
inline constexpr int kMinSiftTilePixels = (4 * kSiftTileMargin) * (4 * kSiftTileMargin);

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
  // Few-feature photos (a small object on a plain background, a low-contrast wall): while a
  // photo yields fewer than `min_features` candidates, SIFT runs again with half the contrast
  // threshold, down to `min_contrast_threshold`; a working copy whose longer side is below
  // `upsample_below_side` that is still short is then detected at twice its size (finer
  // scales). The pass with the most candidates is kept; at most max_features are
  // asked for. 0 disables it. [0, kMaxMaxFeatures]
  // Measured: lowering the threshold for photos that have ~1,300 candidates (the temple's)
  // costs accuracy (templeSparseRing's centres 0.19 -> 0.40 % of the radius), and detecting
  // them at twice their size lets false matches bridge its wide gaps (every second photo:
  // 3 -> 18 deg); for a dim ring of 240-candidate photos the two together turn a broken
  // model (33 deg) into 1.2 deg (tests/few_features_test). Hence a low default.
  int min_features = kDefaultMinFeatures;
  // (0, contrast_threshold]
  double min_contrast_threshold = 0.005;
  // [0, 20000]; 0 never upsamples.
  int upsample_below_side = 1000;
  // Edge-response threshold (Lowe's r). [1, 100]
  double edge_threshold = 10.0;
  // Scale levels per octave. [1, 8]
  int octave_layers = 3;
  // Working copies with more pixels are described in tiles of at most this many pixels
  // (margins included; see above). [kMinSiftTilePixels, 2^30]
  int max_tile_pixels = 2'000'000;

  bool Check(std::string* error) const;
};

// How a photo's features were detected (the pass kept; see min_features).
struct SiftDetection {
  int candidates = 0;               // SIFT candidates before the selection.
  double contrast_threshold = 0.0;  // The threshold of the pass kept.
  bool upsampled = false;           // Detected on a copy of twice the working size.
  int passes = 0;                   // SIFT passes run.
};

// Detects and describes features in `image` (8-bit, grey or BGR, original resolution).
// Deterministic for the same input.
FeatureSet ExtractSiftFeatures(const cv::Mat& image, const SiftOptions& options);
// The same for `image`, a downscaled copy of a photo of `original_size` pixels (read at its
// working size): keypoints and image size are reported in the original's pixels. `detection`,
// when given, says how they were found.
FeatureSet ExtractSiftFeatures(const cv::Mat& image,
                               const SiftOptions& options,
                               cv::Size original_size,
                               SiftDetection* detection = nullptr);

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
