// Global image comparison: which pairs are worth matching, decided before matching them.
//
// ARC3D compared subsampled versions of every pair; we do the same with a cheap signal:
//  - small sets (up to `exhaustive_max_images` photos): every pair is scored by matching only
//    the `num_probe_features` strongest features of each image (a ~1/64 of the full matching
//    cost); the score is the fraction of probe features with a mutual ratio-test match;
//  - larger sets: each image gets a VLAD vector (Jégou et al. 2010, "Aggregating local
//    descriptors into a compact image representation") over a codebook trained on the job's
//    own descriptors (k-means), with intra-normalisation (Arandjelović & Zisserman 2013) and
//    power normalisation; the score is the cosine similarity. Each image keeps its
//    `num_nearest` most similar images, plus its `sequential_neighbors` neighbours in name
//    order (photo sets are often shot in sequence), so matching work grows linearly.
// Either way, each image keeps at least its `min_pairs_per_image` best partners, so a
// wide-baseline photo with a low score still gets a chance to be matched.
#ifndef RECONDUIT_CORE_FEATURE_GLOBAL_COMPARISON_H_
#define RECONDUIT_CORE_FEATURE_GLOBAL_COMPARISON_H_

#include "core/feature/features.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"

#include <Eigen/Core>

#include <string>
#include <utility>
#include <vector>

namespace reconduit {

struct GlobalComparisonOptions {
  // Up to this many images every pair is scored with probe matching; above it, VLAD. [2, 1000]
  int exhaustive_max_images = 60;
  // Strongest features per image used for probe matching. [16, 10000]
  int num_probe_features = 1024;
  // Probe matching: pairs whose share of matched probe features reaches this are kept. [0, 1]
  double min_score = 0.02;
  // Every image keeps at least this many best partners whatever their score. [0, 1000]
  int min_pairs_per_image = 3;
  // VLAD: most similar images kept per image. [1, 1000]
  int num_nearest = 20;
  // VLAD: neighbours in input (name) order always kept on each side. [0, 100]
  int sequential_neighbors = 2;
  // VLAD: codebook size (k-means centres). [4, 1024]
  int vlad_clusters = 64;
  // VLAD: descriptors per image sampled to train the codebook. [16, 100000]
  int vlad_training_per_image = 300;
  // Threads; 0 = all cores.
  int num_threads = 0;

  bool Check(std::string* error) const;
};

struct ImagePair {
  int image1 = -1;  // image1 < image2, indices into the input.
  int image2 = -1;
  double score = 0.0;
};

struct GlobalComparisonResult {
  std::string method;            // "probe_matching" or "vlad".
  Eigen::MatrixXf similarity;    // Symmetric, N x N; diagonal 1.
  std::vector<ImagePair> pairs;  // Chosen pairs, best first.
};

// `features` holds every image's features (only descriptors and keypoint order are used;
// features are assumed strongest-first as ExtractSiftFeatures returns them).
GlobalComparisonResult CompareImages(const std::vector<const FeatureSet*>& features,
                                     const GlobalComparisonOptions& options,
                                     Progress& progress,
                                     const CancelToken& cancel);

// The similarity matrix as a colour picture for the report: one `cell`-pixel square per
// pair, chosen pairs outlined. 8-bit BGR.
cv::Mat RenderSimilarityMatrix(const GlobalComparisonResult& result, int cell = 16);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_FEATURE_GLOBAL_COMPARISON_H_
