// Local features of one image: keypoints and RootSIFT descriptors.
#ifndef RECONDUIT_CORE_FEATURE_FEATURES_H_
#define RECONDUIT_CORE_FEATURE_FEATURES_H_

#include "core/util/status.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace reconduit {

struct Keypoint {
  // Position in pixels of the ORIGINAL image (pixel centres at integer coordinates), even when
  // features were detected on a downscaled working copy.
  float x = 0.0f;
  float y = 0.0f;
  // Detection scale in original-image pixels (OpenCV's KeyPoint::size scaled back).
  float scale = 0.0f;
  // Dominant gradient orientation, in radians.
  float orientation = 0.0f;
  // Detector response (DoG contrast); larger is stronger.
  float response = 0.0f;
};

struct FeatureSet {
  int image_width = 0;  // Original image size in pixels.
  int image_height = 0;
  std::vector<Keypoint> keypoints;
  // One row of 128 bytes per keypoint: RootSIFT (Arandjelović & Zisserman 2012, "Three things
  // everyone should know to improve object retrieval"): the SIFT vector L1-normalised and
  // square-rooted, so that Euclidean distance compares as the Hellinger kernel on the
  // original; then quantised as round(min(255, 512 v)) like COLMAP (v has unit L2 norm).
  cv::Mat descriptors;  // CV_8U, keypoints.size() x 128.

  std::size_t size() const { return keypoints.size(); }
};

// Binary storage of a FeatureSet (little-endian host format, with a magic and version, and a
// size check so a truncated file is an error, not garbage).
Status WriteFeatures(const std::filesystem::path& path, const FeatureSet& features);
Result<FeatureSet> ReadFeatures(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_FEATURE_FEATURES_H_
