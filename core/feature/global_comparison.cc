#include "core/feature/global_comparison.h"

#include "core/feature/matcher.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <numeric>
#include <set>
#include <sstream>

namespace reconduit {
namespace {

std::vector<std::pair<int, int>> AllPairs(int n) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
  }
  return pairs;
}

Eigen::MatrixXf ProbeSimilarity(const std::vector<const FeatureSet*>& features,
                                const GlobalComparisonOptions& options,
                                Progress& progress,
                                const CancelToken& cancel) {
  const int n = static_cast<int>(features.size());
  std::vector<DescriptorMatrix> probes(n);
  for (int i = 0; i < n; ++i) {
    DescriptorMatrix all = ToDescriptorMatrix(*features[i]);
    probes[i] = all.topRows(std::min<Eigen::Index>(all.rows(), options.num_probe_features));
  }
  const auto pairs = AllPairs(n);
  Eigen::MatrixXf similarity = Eigen::MatrixXf::Identity(n, n);
  progress.Restart(pairs.size(), "comparing every pair of photos");
  ParallelFor(
      0, pairs.size(),
      [&](std::size_t k) {
        cancel.ThrowIfCanceled();
        const auto [i, j] = pairs[k];
        const auto matches = MatchDescriptors(probes[i], probes[j], MatchingOptions());
        const Eigen::Index denominator = std::min(probes[i].rows(), probes[j].rows());
        const float score =
            denominator > 0 ? static_cast<float>(matches.size()) / denominator : 0.0f;
        similarity(i, j) = similarity(j, i) = score;  // Distinct cells per pair: no race.
        progress.Advance();
      },
      options.num_threads);
  return similarity;
}

Eigen::MatrixXf VladSimilarity(const std::vector<const FeatureSet*>& features,
                               const GlobalComparisonOptions& options,
                               Progress& progress,
                               const CancelToken& cancel) {
  const int n = static_cast<int>(features.size());
  // Training sample: evenly spaced descriptors of every image (deterministic).
  cv::Mat samples;
  for (const FeatureSet* f : features) {
    const int rows = f->descriptors.rows;
    const int take = std::min(rows, options.vlad_training_per_image);
    for (int k = 0; k < take; ++k) {
      cv::Mat row;
      f->descriptors.row(static_cast<int>(static_cast<long>(k) * rows / take))
          .convertTo(row, CV_32F);
      samples.push_back(row);
    }
  }
  const int clusters = std::min(options.vlad_clusters, std::max(1, samples.rows));
  progress.Restart(n + 1, "training the visual vocabulary");
  cv::Mat labels, centers;
  cv::theRNG().state = 0x5eed;  // cv::kmeans draws from the thread's RNG: make it repeatable.
  if (samples.rows > 0) {
    cv::kmeans(samples, clusters, labels,
               cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 25, 1e-3), 1,
               cv::KMEANS_PP_CENTERS, centers);
  }
  progress.Advance();
  cancel.ThrowIfCanceled();

  const int dim = clusters * 128;
  Eigen::MatrixXf vlad = Eigen::MatrixXf::Zero(n, dim);
  Eigen::Matrix<float, Eigen::Dynamic, 128, Eigen::RowMajor> c(clusters, 128);
  for (int k = 0; k < clusters && !centers.empty(); ++k) {
    for (int d = 0; d < 128; ++d) c(k, d) = centers.at<float>(k, d);
  }
  progress.SetMessage("describing each photo");
  ParallelFor(
      0, n,
      [&](std::size_t i) {
        cancel.ThrowIfCanceled();
        const cv::Mat& desc = features[i]->descriptors;
        Eigen::MatrixXf v = Eigen::MatrixXf::Zero(clusters, 128);
        for (int r = 0; r < desc.rows; ++r) {
          Eigen::Matrix<float, 1, 128> x;
          for (int d = 0; d < 128; ++d) x(d) = desc.at<std::uint8_t>(r, d);
          int best = 0;
          float best_d = std::numeric_limits<float>::infinity();
          for (int k = 0; k < clusters; ++k) {
            const float dist = (c.row(k) - x).squaredNorm();
            if (dist < best_d) {
              best_d = dist;
              best = k;
            }
          }
          v.row(best) += x - c.row(best);
        }
        for (int k = 0; k < clusters; ++k) {  // Intra-normalisation.
          const float norm = v.row(k).norm();
          if (norm > 0) v.row(k) /= norm;
        }
        Eigen::RowVectorXf flat = Eigen::Map<Eigen::RowVectorXf>(v.data(), dim);
        flat = flat.unaryExpr([](float a) { return std::copysign(std::sqrt(std::abs(a)), a); });
        const float norm = flat.norm();
        if (norm > 0) flat /= norm;
        vlad.row(i) = flat;
        progress.Advance();
      },
      options.num_threads);
  Eigen::MatrixXf similarity = vlad * vlad.transpose();
  similarity.diagonal().setOnes();
  return similarity;
}

}  // namespace

bool GlobalComparisonOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (exhaustive_max_images < 2 || exhaustive_max_images > 1000) {
    m << "exhaustive_max_images must be in [2, 1000], got " << exhaustive_max_images;
  } else if (num_probe_features < 16 || num_probe_features > 10000) {
    m << "num_probe_features must be in [16, 10000], got " << num_probe_features;
  } else if (!(min_score >= 0.0 && min_score <= 1.0)) {
    m << "min_score must be in [0, 1], got " << min_score;
  } else if (min_pairs_per_image < 0 || min_pairs_per_image > 1000) {
    m << "min_pairs_per_image must be in [0, 1000], got " << min_pairs_per_image;
  } else if (num_nearest < 1 || num_nearest > 1000) {
    m << "num_nearest must be in [1, 1000], got " << num_nearest;
  } else if (sequential_neighbors < 0 || sequential_neighbors > 100) {
    m << "sequential_neighbors must be in [0, 100], got " << sequential_neighbors;
  } else if (vlad_clusters < 4 || vlad_clusters > 1024) {
    m << "vlad_clusters must be in [4, 1024], got " << vlad_clusters;
  } else if (vlad_training_per_image < 16 || vlad_training_per_image > 100000) {
    m << "vlad_training_per_image must be in [16, 100000], got " << vlad_training_per_image;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

GlobalComparisonResult CompareImages(const std::vector<const FeatureSet*>& features,
                                     const GlobalComparisonOptions& options,
                                     Progress& progress,
                                     const CancelToken& cancel) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const Timer timer;
  const int n = static_cast<int>(features.size());
  GlobalComparisonResult result;
  const bool exhaustive = n <= options.exhaustive_max_images;
  result.method = exhaustive ? "probe_matching" : "vlad";
  result.similarity = exhaustive ? ProbeSimilarity(features, options, progress, cancel)
                                 : VladSimilarity(features, options, progress, cancel);

  std::set<std::pair<int, int>> chosen;
  auto add = [&](int i, int j) {
    if (i != j) chosen.emplace(std::min(i, j), std::max(i, j));
  };
  for (int i = 0; i < n; ++i) {
    std::vector<int> others;
    for (int j = 0; j < n; ++j) {
      if (j != i) others.push_back(j);
    }
    std::stable_sort(others.begin(), others.end(), [&](int a, int b) {
      return result.similarity(i, a) > result.similarity(i, b);
    });
    const int keep = exhaustive ? options.min_pairs_per_image
                                : std::max(options.min_pairs_per_image, options.num_nearest);
    for (int k = 0; k < std::min<int>(keep, others.size()); ++k) add(i, others[k]);
    if (exhaustive) {
      for (int j : others) {
        if (result.similarity(i, j) >= options.min_score) add(i, j);
      }
    } else {
      for (int d = 1; d <= options.sequential_neighbors; ++d) {
        if (i + d < n) add(i, i + d);
      }
    }
  }
  for (const auto& [i, j] : chosen) result.pairs.push_back({i, j, result.similarity(i, j)});
  std::stable_sort(result.pairs.begin(), result.pairs.end(),
                   [](const ImagePair& a, const ImagePair& b) { return a.score > b.score; });
  progress.Finish();
  LOG_INFO << "global comparison (" << result.method << "): " << n << " photos, "
           << result.pairs.size() << " of " << n * (n - 1) / 2 << " pairs chosen in "
           << timer.ElapsedSeconds() << " s";
  return result;
}

cv::Mat RenderSimilarityMatrix(const GlobalComparisonResult& result, int cell) {
  const int n = static_cast<int>(result.similarity.rows());
  float max_off = 0.0f;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      if (i != j) max_off = std::max(max_off, result.similarity(i, j));
    }
  }
  cv::Mat gray(n * cell, n * cell, CV_8U);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const float v = i == j ? 1.0f : (max_off > 0 ? result.similarity(i, j) / max_off : 0.0f);
      gray(cv::Rect(j * cell, i * cell, cell, cell))
          .setTo(cv::Scalar(std::clamp(v, 0.0f, 1.0f) * 255));
    }
  }
  cv::Mat colour;
  cv::applyColorMap(gray, colour, cv::COLORMAP_VIRIDIS);
  if (cell >= 4) {
    for (const ImagePair& p : result.pairs) {
      for (const auto& [r, c] : {std::pair(p.image1, p.image2), std::pair(p.image2, p.image1)}) {
        cv::rectangle(colour, cv::Rect(c * cell, r * cell, cell, cell), cv::Scalar(255, 255, 255),
                      1);
      }
    }
  }
  return colour;
}

}  // namespace reconduit
