#include "core/feature/matcher.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cblas.h>
#include <cmath>
#include <limits>
#include <mutex>
#include <sstream>

extern "C" void openblas_set_num_threads(int num_threads);

namespace reconduit {
namespace {

// Rows per block: 1024 x n floats is 32 MiB at n = 8192.
constexpr int kBlockRows = 1024;

struct Best2 {
  float d1 = std::numeric_limits<float>::infinity();  // Squared distances.
  float d2 = std::numeric_limits<float>::infinity();
  int index = -1;
  void Offer(float d, int i) {
    if (d < d1) {
      d2 = d1;
      d1 = d;
      index = i;
    } else if (d < d2) {
      d2 = d;
    }
  }
};

// The matches that pass the distance test, the ratio test (on squared distances; a lone
// candidate has d2 = infinity) and, when asked, the mutual check: nearest_to_2[j] is the
// feature of image 1 nearest to feature j of image 2 (-1 for none). Sorted by index1.
std::vector<FeatureMatch> SelectMatches(const std::vector<Best2>& best_for_1,
                                        const std::vector<int>& nearest_to_2,
                                        double max_distance,
                                        double max_ratio,
                                        bool cross_check) {
  const float max_distance2 = static_cast<float>(max_distance * max_distance);
  const float max_ratio2 = static_cast<float>(max_ratio * max_ratio);
  std::vector<FeatureMatch> matches;
  for (int i = 0; i < static_cast<int>(best_for_1.size()); ++i) {
    const Best2& b = best_for_1[i];
    if (b.index < 0 || b.d1 > max_distance2) continue;
    if (b.d1 >= max_ratio2 * b.d2) continue;
    if (cross_check && nearest_to_2[b.index] != i) continue;
    matches.push_back({i, b.index});
  }
  return matches;
}

// Columns per step of ScanRow. More than 16 on purpose: GCC completely unrolls loops of up to
// 16 iterations before it vectorises, and its first loop (with reductions) then no longer
// vectorises.
constexpr int kChunk = 32;

// One row i of the distance block (dots[j] = descriptor i · descriptor j of image 2). Offers
// every distance d(i, j) = max(0, |i|² + |j|² - 2 i·j) to column j's nearest row (col_d1,
// col_index) and to the row's Best2, which it returns: the same state as Best2::Offer(d, j)
// over j = 0, 1, ... for the row and Offer(d, i) over the rows i = 0, 1, ... for a column,
// ties included (strict <: the lowest index keeps a tie; a repeated minimum gives d2 == d1).
//
// Nearly all offers change nothing: a column only takes d < col_d1[j], the row only d < d2
// (Offer with d >= d2 is a no-op). So a branch-free loop that vectorises computes kChunk
// distances at a time and checks for such a d; only a chunk that holds one runs the updates,
// on the same d values: the columns with selects (vectorised), the row with the same Offer
// calls in the same order. Past the first rows and columns few chunks need them (about one
// in 17 at 8192 x 8192 random descriptors).
Best2 ScanRow(const float* __restrict dots,
              const float* __restrict norms2,
              float norm1,
              int i,
              int n2,
              float* __restrict col_d1,
              int* __restrict col_index) {
  Best2 best;
  int start = 0;
  for (; start + kChunk <= n2; start += kChunk) {
    float d[kChunk];
    int column_hit = 0, row_hit = 0;
    const float d2 = best.d2;
    for (int k = 0; k < kChunk; ++k) {
      const int j = start + k;
      d[k] = std::max(0.0f, norm1 + norms2[j] - 2.0f * dots[j]);
      column_hit |= -static_cast<int>(d[k] < col_d1[j]);
      row_hit |= -static_cast<int>(d[k] < d2);
    }
    if (column_hit != 0) {
      for (int k = 0; k < kChunk; ++k) {
        const int j = start + k;
        // A mask, not `d[k] < col_d1[j] ? i : col_index[j]`: GCC turns that into a
        // conditional store, which does not vectorise.
        const int keep = static_cast<int>(d[k] < col_d1[j]) - 1;  // 0 where d[k] is nearer.
        col_index[j] = (col_index[j] & keep) | (i & ~keep);
        col_d1[j] = std::min(col_d1[j], d[k]);
      }
    }
    if (row_hit != 0) {
      for (int k = 0; k < kChunk; ++k) best.Offer(d[k], start + k);
    }
  }
  for (int j = start; j < n2; ++j) {  // The last n2 % kChunk columns.
    const float d = std::max(0.0f, norm1 + norms2[j] - 2.0f * dots[j]);
    if (d < col_d1[j]) {
      col_d1[j] = d;
      col_index[j] = i;
    }
    best.Offer(d, j);
  }
  return best;
}

void UseSingleThreadedBlas() {
  static std::once_flag once;
  std::call_once(once, [] { openblas_set_num_threads(1); });
}

}  // namespace

bool MatchingOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (!(max_ratio > 0.0 && max_ratio <= 1.0)) {
    m << "max_ratio must be in (0, 1], got " << max_ratio;
  } else if (!(max_distance > 0.0 && max_distance <= 2.0)) {
    m << "max_distance must be in (0, 2], got " << max_distance;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

DescriptorMatrix ToDescriptorMatrix(const FeatureSet& features) {
  THROW_CHECK(features.descriptors.empty() || features.descriptors.cols == 128);
  DescriptorMatrix matrix(features.descriptors.rows, 128);
  for (int r = 0; r < features.descriptors.rows; ++r) {
    const std::uint8_t* row = features.descriptors.ptr<std::uint8_t>(r);
    for (int c = 0; c < 128; ++c) matrix(r, c) = static_cast<float>(row[c]);
    const float norm = matrix.row(r).norm();
    if (norm > 0.0f) matrix.row(r) /= norm;
  }
  return matrix;
}

std::vector<FeatureMatch> MatchDescriptors(const DescriptorMatrix& descriptors1,
                                           const DescriptorMatrix& descriptors2,
                                           const MatchingOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const int n1 = static_cast<int>(descriptors1.rows());
  const int n2 = static_cast<int>(descriptors2.rows());

  if (n1 == 0 || n2 == 0) return {};
  UseSingleThreadedBlas();

  const Eigen::VectorXf norms2 = descriptors2.rowwise().squaredNorm();
  std::vector<Best2> best_for_1(n1);
  // Per feature of image 2, its nearest feature of image 1 and that distance (arrays for
  // ScanRow; the mutual check needs no second-nearest distance for them).
  std::vector<float> col_d1(n2, std::numeric_limits<float>::infinity());
  std::vector<int> nearest_to_2(n2, -1);
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> dots(
      std::min(kBlockRows, n1), n2);
  for (int start = 0; start < n1; start += kBlockRows) {
    const int rows = std::min(kBlockRows, n1 - start);
    // dots = descriptors1[start:start+rows] * descriptors2ᵀ
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, rows, n2, 128, 1.0f,
                descriptors1.data() + static_cast<std::ptrdiff_t>(start) * 128, 128,
                descriptors2.data(), 128, 0.0f, dots.data(), n2);
    for (int r = 0; r < rows; ++r) {
      const int i = start + r;
      best_for_1[i] =
          ScanRow(dots.data() + static_cast<std::ptrdiff_t>(r) * n2, norms2.data(),
                  descriptors1.row(i).squaredNorm(), i, n2, col_d1.data(), nearest_to_2.data());
    }
  }

  return SelectMatches(best_for_1, nearest_to_2, options.max_distance, options.max_ratio,
                       options.cross_check);
}

bool GuidedMatchingOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (!(max_sampson_px > 0.0)) {
    m << "max_sampson_px must be positive, got " << max_sampson_px;
  } else if (!(max_ratio > 0.0 && max_ratio <= 1.0)) {
    m << "max_ratio must be in (0, 1], got " << max_ratio;
  } else if (!(max_distance > 0.0 && max_distance <= 2.0)) {
    m << "max_distance must be in (0, 2], got " << max_distance;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::vector<FeatureMatch> GuidedMatchDescriptors(const DescriptorMatrix& descriptors1,
                                                 const DescriptorMatrix& descriptors2,
                                                 const std::vector<Eigen::Vector2d>& keypoints1,
                                                 const std::vector<Eigen::Vector2d>& keypoints2,
                                                 const Eigen::Matrix3d& F,
                                                 const GuidedMatchingOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const int n1 = static_cast<int>(descriptors1.rows());
  const int n2 = static_cast<int>(descriptors2.rows());
  THROW_CHECK_EQ(keypoints1.size(), static_cast<std::size_t>(n1));
  THROW_CHECK_EQ(keypoints2.size(), static_cast<std::size_t>(n2));

  if (n1 == 0 || n2 == 0) return {};

  // Sampson distance² of (x1, x2): (x2ᵀ F x1)² / (|(F x1)_xy|² + |(Fᵀ x2)_xy|²). The image-2
  // terms are computed once: the epipolar lines Fᵀ x2 in image 1, and x2 itself, in doubles
  // (pixel coordinates in the thousands square to values that floats would round badly).
  std::vector<Eigen::Vector3d> points2(n2);
  std::vector<double> line1_norm2(n2);
  for (int j = 0; j < n2; ++j) {
    points2[j] = keypoints2[j].homogeneous();
    line1_norm2[j] = (F.transpose() * points2[j]).head<2>().squaredNorm();
  }
  const double max_sampson2 = options.max_sampson_px * options.max_sampson_px;

  std::vector<Best2> best_for_1(n1);
  std::vector<Best2> best_for_2(n2);
  for (int i = 0; i < n1; ++i) {
    const Eigen::Vector3d line2 = F * keypoints1[i].homogeneous();
    const double line2_norm2 = line2.head<2>().squaredNorm();
    const auto d1 = descriptors1.row(i);
    for (int j = 0; j < n2; ++j) {
      const double e = line2.dot(points2[j]);
      const double denominator = line2_norm2 + line1_norm2[j];
      if (!(e * e <= max_sampson2 * denominator)) continue;  // Also skips 0/0.
      // Unit-norm descriptors: |a - b|² = 2 - 2 a·b.
      const float d = std::max(0.0f, 2.0f - 2.0f * d1.dot(descriptors2.row(j)));
      best_for_1[i].Offer(d, j);
      best_for_2[j].Offer(d, i);
    }
  }

  std::vector<int> nearest_to_2(n2);
  for (int j = 0; j < n2; ++j) nearest_to_2[j] = best_for_2[j].index;
  return SelectMatches(best_for_1, nearest_to_2, options.max_distance, options.max_ratio,
                       options.cross_check);
}

}  // namespace reconduit
