#include "core/feature/global_comparison.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

namespace reconduit {
namespace {

// A chain of photos: photo i sees "places" i and i + 1, so neighbours in the chain share half
// their features (with noise) and photos two apart share nothing.
std::vector<FeatureSet> ChainOfPhotos(int n, int per_place, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::gamma_distribution<float> gamma(0.5f, 1.0f);  // Sparse, SIFT-like histograms.
  std::normal_distribution<float> noise(0.0f, 4.0f);
  std::vector<cv::Mat> places;
  for (int p = 0; p <= n; ++p) {
    cv::Mat place(per_place, 128, CV_32F);
    for (int r = 0; r < per_place; ++r) {
      for (int c = 0; c < 128; ++c) place.at<float>(r, c) = gamma(rng);
      place.row(r) *= 512.0 / cv::norm(place.row(r));
    }
    places.push_back(place);
  }
  std::vector<FeatureSet> photos(n);
  for (int i = 0; i < n; ++i) {
    FeatureSet& f = photos[i];
    f.image_width = 640;
    f.image_height = 480;
    cv::Mat rows;
    for (int p : {i, i + 1}) {
      for (int r = 0; r < per_place; ++r) {
        cv::Mat row = places[p].row(r).clone();
        for (int c = 0; c < 128; ++c)
          row.at<float>(0, c) = std::max(0.0f, row.at<float>(0, c) + noise(rng));
        rows.push_back(row);
      }
    }
    rows.convertTo(f.descriptors, CV_8U);
    f.keypoints.resize(f.descriptors.rows);
  }
  return photos;
}

std::vector<const FeatureSet*> Pointers(const std::vector<FeatureSet>& photos) {
  std::vector<const FeatureSet*> out;
  for (const FeatureSet& f : photos) out.push_back(&f);
  return out;
}

TEST(GlobalComparisonOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(GlobalComparisonOptions().Check(&error)) << error;
}

TEST(CompareImages, ProbeMatchingFindsTheChain) {
  const auto photos = ChainOfPhotos(8, 150, 1);
  GlobalComparisonOptions options;
  options.min_pairs_per_image = 1;
  Progress progress;
  const auto result = CompareImages(Pointers(photos), options, progress, CancelToken());
  EXPECT_EQ(result.method, "probe_matching");
  ASSERT_EQ(result.similarity.rows(), 8);
  std::set<std::pair<int, int>> chosen;
  for (const ImagePair& p : result.pairs) {
    EXPECT_LT(p.image1, p.image2);
    chosen.emplace(p.image1, p.image2);
  }
  for (int i = 0; i + 1 < 8; ++i) {
    EXPECT_TRUE(chosen.count({i, i + 1})) << i;
    EXPECT_GT(result.similarity(i, i + 1), 0.3f);
    if (i + 2 < 8) {
      EXPECT_LT(result.similarity(i, i + 2), 0.02f);
    }
  }
  EXPECT_EQ(chosen.size(), 7u) << "unrelated photos are not matched";
  EXPECT_EQ(progress.fraction(), 1.0);
}

TEST(CompareImages, MinPairsPerImageKeepsBestPartnersEvenBelowTheScore) {
  const auto photos = ChainOfPhotos(5, 100, 2);
  GlobalComparisonOptions options;
  options.min_score = 1.0;          // Nothing passes the score...
  options.min_pairs_per_image = 2;  // ...but every photo keeps its two best partners.
  Progress progress;
  const auto result = CompareImages(Pointers(photos), options, progress, CancelToken());
  std::vector<int> degree(5, 0);
  for (const ImagePair& p : result.pairs) {
    ++degree[p.image1];
    ++degree[p.image2];
  }
  for (int d : degree) EXPECT_GE(d, 2);
}

TEST(CompareImages, VladRanksChainNeighboursFirst) {
  const auto photos = ChainOfPhotos(12, 200, 3);
  GlobalComparisonOptions options;
  options.exhaustive_max_images = 4;  // Force VLAD.
  options.num_nearest = 2;
  options.sequential_neighbors = 0;
  options.min_pairs_per_image = 0;
  options.vlad_clusters = 16;
  Progress progress;
  const auto result = CompareImages(Pointers(photos), options, progress, CancelToken());
  EXPECT_EQ(result.method, "vlad");
  for (int i = 0; i < 12; ++i) {
    int best = -1;
    for (int j = 0; j < 12; ++j) {
      if (j != i && (best < 0 || result.similarity(i, j) > result.similarity(i, best))) best = j;
    }
    EXPECT_EQ(std::abs(best - i), 1) << "photo " << i << " is most like " << best;
  }
  EXPECT_LE(result.pairs.size(), 12u * 2u) << "linear in the number of photos";
}

TEST(CompareImages, Cancellation) {
  const auto photos = ChainOfPhotos(4, 50, 4);
  CancelToken cancel;
  cancel.RequestCancel();
  Progress progress;
  EXPECT_THROW(CompareImages(Pointers(photos), GlobalComparisonOptions(), progress, cancel),
               CanceledError);
}

TEST(RenderSimilarityMatrix, OneCellPerPair) {
  const auto photos = ChainOfPhotos(3, 50, 5);
  Progress progress;
  const auto result =
      CompareImages(Pointers(photos), GlobalComparisonOptions(), progress, CancelToken());
  const cv::Mat picture = RenderSimilarityMatrix(result, 10);
  EXPECT_EQ(picture.rows, 30);
  EXPECT_EQ(picture.cols, 30);
  EXPECT_EQ(picture.type(), CV_8UC3);
}

}  // namespace
}  // namespace reconduit
