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
  // Offers in any order of i, ending in the state Offer leaves after the same offers in
  // ascending i: (d1, d2) are the two smallest d offered (d2 == d1 when the smallest repeats)
  // in either, and index is the lowest i among those that offered d1 (Offer keeps the first).
  // An equal d with a lower i takes the index and, the smallest now repeating, sets d2 = d1.
  void OfferUnordered(float d, int i) {
    if (d < d1 || (d == d1 && i < index)) {
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

// GuidedMatchDescriptors tests a pair (x1, x2) as the plain loop over all pairs did, on the same
// values: x2 = (x, y), line1_norm2 = |(Fᵀ x2)_xy|², line2 = F x1 and line2_norm2 = |line2_xy|²,
// e = x2ᵀ line2 = l0 x + l1 y + l2 summed in the order of Eigen's Vector3d dot (l0 x + l1 y
// first; l2 · 1 is l2), a candidate iff e² <= max_sampson2 (line2_norm2 + line1_norm2). But
// testing all n1 x n2 pairs was nearly all of its time while 0.6 % pass (1.5 px on 800 x 600
// photos), so image 2's keypoints are kept in the cells of a grid, in blocks of cells, and a
// row skips the blocks and cells its band cannot reach (SkipGroups).

// Cells of about this many keypoints (8192 keypoints: 1024 cells of ~25 px on 800 x 600), in
// blocks of kBlockSide x kBlockSide cells.
constexpr int kKeypointsPerCell = 8;
constexpr int kBlockSide = 4;

// Each point's key in a grid of about n / kKeypointsPerCell cells over the bounding box of the
// finite points: its block, then its cell in the block (row-major both). The other points get
// the last key, num_keys - 1.
struct GridKeys {
  std::vector<int> key;
  int num_keys = 1;
};

GridKeys MakeGridKeys(const std::vector<Eigen::Vector2d>& points, const std::vector<char>& finite) {
  const int n = static_cast<int>(points.size());
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x,
         max_y = -min_x;
  for (int k = 0; k < n; ++k) {
    if (!finite[k]) continue;
    min_x = std::min(min_x, points[k].x());
    max_x = std::max(max_x, points[k].x());
    min_y = std::min(min_y, points[k].y());
    max_y = std::max(max_y, points[k].y());
  }
  // A grid shaped like the bounding box; one cell if it is empty or too large to subtract in.
  double width = std::max(0.0, max_x - min_x), height = std::max(0.0, max_y - min_y);
  if (!std::isfinite(width) || !std::isfinite(height)) width = height = 0.0;
  const double target = std::max(1.0, static_cast<double>(n) / kKeypointsPerCell);
  int columns = 1, rows = 1;
  if (width > 0.0 && height > 0.0) {
    columns = static_cast<int>(std::clamp(std::sqrt(target * width / height), 1.0, target));
    rows = static_cast<int>(std::clamp(target / columns, 1.0, target));
  } else if (width > 0.0) {
    columns = static_cast<int>(target);
  } else if (height > 0.0) {
    rows = static_cast<int>(target);
  }
  const int block_columns = (columns + kBlockSide - 1) / kBlockSide;
  const int block_rows = (rows + kBlockSide - 1) / kBlockSide;
  constexpr int kCellsPerBlock = kBlockSide * kBlockSide;
  GridKeys keys;
  keys.num_keys = block_columns * block_rows * kCellsPerBlock + 1;
  keys.key.resize(n);
  for (int k = 0; k < n; ++k) {
    if (!finite[k]) {
      keys.key[k] = keys.num_keys - 1;
      continue;
    }
    const int column =
        width > 0.0
            ? std::min(columns - 1, static_cast<int>((points[k].x() - min_x) / width * columns))
            : 0;
    const int row =
        height > 0.0 ? std::min(rows - 1, static_cast<int>((points[k].y() - min_y) / height * rows))
                     : 0;
    const int block = (row / kBlockSide) * block_columns + column / kBlockSide;
    keys.key[k] = block * kCellsPerBlock + (row % kBlockSide) * kBlockSide + column % kBlockSide;
  }
  return keys;
}

// 0 .. n - 1 by ascending key, ascending index among equal keys (a counting sort).
std::vector<int> SortByKey(const GridKeys& keys) {
  std::vector<int> next(keys.num_keys + 1, 0);
  for (const int key : keys.key) ++next[key + 1];
  for (int k = 0; k < keys.num_keys; ++k) next[k + 1] += next[k];
  std::vector<int> order(keys.key.size());
  for (int k = 0; k < static_cast<int>(keys.key.size()); ++k) order[next[keys.key[k]]++] = k;
  return order;
}

// Groups of image-2 keypoints (cells, or blocks of cells): the centre of their bounding box, the
// half extents, their largest line1_norm2.
struct GroupBounds {
  std::vector<double> centre_x, centre_y, half_x, half_y, max_line1_norm2;

  // Bounds of the points [from, to) of the arrays.
  void Add(const double* x, const double* y, const double* line1_norm2, int from, int to) {
    double lo_x = std::numeric_limits<double>::infinity(), hi_x = -lo_x, lo_y = lo_x, hi_y = -lo_x,
           most = 0.0;
    for (int k = from; k < to; ++k) {
      lo_x = std::min(lo_x, x[k]);
      hi_x = std::max(hi_x, x[k]);
      lo_y = std::min(lo_y, y[k]);
      hi_y = std::max(hi_y, y[k]);
      most = std::max(most, line1_norm2[k]);
    }
    const double cx = 0.5 * (lo_x + hi_x), cy = 0.5 * (lo_y + hi_y);
    centre_x.push_back(cx);
    centre_y.push_back(cy);
    half_x.push_back(std::max(hi_x - cx, cx - lo_x));
    half_y.push_back(std::max(hi_y - cy, cy - lo_y));
    max_line1_norm2.push_back(most);
  }
  // A group that SkipGroups never skips (infinite extents), for non-finite points.
  void AddUnbounded() {
    const double inf = std::numeric_limits<double>::infinity();
    centre_x.push_back(0.0);
    centre_y.push_back(0.0);
    half_x.push_back(inf);
    half_y.push_back(inf);
    max_line1_norm2.push_back(inf);
  }
};

// Image 2's keypoints ordered by grid cell, the cells grouped in blocks.
struct EpipolarGrid {
  // Keypoints in that order (ascending index within a cell): x, y, line1_norm2, index.
  std::vector<double> x, y, line1_norm2;
  std::vector<int> index;
  // Non-empty cells: keypoints [cell_begin[c], cell_begin[c + 1]). Non-empty blocks: cells
  // [block_begin[b], block_begin[b + 1]). The keypoints with a non-finite coordinate or
  // line1_norm2 are the last block, of one cell, both unbounded.
  std::vector<int> cell_begin, block_begin;
  GroupBounds cells, blocks;
  // Largest |x| and |y| of the finite keypoints: bounds for the rounding errors of e.
  double max_abs_x = 0.0, max_abs_y = 0.0;
};

EpipolarGrid MakeEpipolarGrid(const std::vector<Eigen::Vector2d>& keypoints2,
                              const Eigen::Matrix3d& F) {
  const int n2 = static_cast<int>(keypoints2.size());
  std::vector<double> norms(n2);
  std::vector<char> finite(n2);
  EpipolarGrid grid;
  for (int j = 0; j < n2; ++j) {
    const Eigen::Vector2d& p = keypoints2[j];
    norms[j] = (F.transpose() * p.homogeneous()).head<2>().squaredNorm();
    finite[j] = std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(norms[j]);
    if (!finite[j]) continue;
    grid.max_abs_x = std::max(grid.max_abs_x, std::abs(p.x()));
    grid.max_abs_y = std::max(grid.max_abs_y, std::abs(p.y()));
  }
  const GridKeys keys = MakeGridKeys(keypoints2, finite);
  grid.index = SortByKey(keys);
  for (const int j : grid.index) {
    grid.x.push_back(keypoints2[j].x());
    grid.y.push_back(keypoints2[j].y());
    grid.line1_norm2.push_back(norms[j]);
  }
  constexpr int kCellsPerBlock = kBlockSide * kBlockSide;
  for (int k = 0; k < n2; ++k) {
    const int key = keys.key[grid.index[k]];
    if (k > 0 && key == keys.key[grid.index[k - 1]]) continue;
    if (k == 0 || key / kCellsPerBlock != keys.key[grid.index[k - 1]] / kCellsPerBlock) {
      grid.block_begin.push_back(static_cast<int>(grid.cell_begin.size()));
    }
    grid.cell_begin.push_back(k);
  }
  grid.cell_begin.push_back(n2);
  grid.block_begin.push_back(static_cast<int>(grid.cell_begin.size()) - 1);
  const int num_cells = static_cast<int>(grid.cell_begin.size()) - 1;
  const int num_blocks = static_cast<int>(grid.block_begin.size()) - 1;
  const bool unbounded_last = n2 > 0 && keys.key[grid.index[n2 - 1]] == keys.num_keys - 1;
  for (int c = 0; c < num_cells; ++c) {
    if (unbounded_last && c == num_cells - 1) {
      grid.cells.AddUnbounded();
    } else {
      grid.cells.Add(grid.x.data(), grid.y.data(), grid.line1_norm2.data(), grid.cell_begin[c],
                     grid.cell_begin[c + 1]);
    }
  }
  for (int b = 0; b < num_blocks; ++b) {
    if (unbounded_last && b == num_blocks - 1) {
      grid.blocks.AddUnbounded();
    } else {
      grid.blocks.Add(grid.x.data(), grid.y.data(), grid.line1_norm2.data(),
                      grid.cell_begin[grid.block_begin[b]],
                      grid.cell_begin[grid.block_begin[b + 1]]);
    }
  }
  return grid;
}

// One row's line in image 2 and what SkipGroups needs of it.
struct RowLine {
  double l0, l1, l2;  // line2 = F x1.
  double line2_norm2;
  double max_sampson2;
  double absolute;  // The absolute slack of SkipGroups.
};

RowLine MakeRowLine(const Eigen::Vector3d& line2,
                    double line2_norm2,
                    double max_sampson2,
                    const EpipolarGrid& grid) {
  RowLine r;
  r.l0 = line2.x();
  r.l1 = line2.y();
  r.l2 = line2.z();
  r.line2_norm2 = line2_norm2;
  r.max_sampson2 = max_sampson2;
  r.absolute =
      1e-9 * (std::abs(r.l0) * grid.max_abs_x + std::abs(r.l1) * grid.max_abs_y + std::abs(r.l2)) +
      1e-150;
  return r;
}

// For the groups [from, to): skip[g] > 0 where no keypoint of group g passes the row's epipolar
// test, <= 0 or NaN otherwise; in one loop GCC vectorises.
//
// Why that is safe. Let E(p) = l0 x + l1 y + l2 exactly, for the computed line2, and
// S = |l0| max|x| + |l1| max|y| + |l2|. The computed e of a keypoint is within 3u S of E
// (u = 2^-53; three terms summed), and it passes only if |e| <= sqrt(R) (1 + 2u) with
// R = max_sampson2 (line2_norm2 + line1_norm2) <= R_g = max_sampson2 (line2_norm2 + the group's
// largest line1_norm2); underflow adds at most 1e-154 to these bounds. In its group,
// |x - cx| <= hx and |y - cy| <= hy (up to a rounding of hx, hy), so |E(centre)| <= |E(p)| +
// |l0| hx + |l1| hy. Hence, with g = |e_centre| - (|l0| hx + |l1| hy) (1 + 1e-9) - 1e-9 S -
// 1e-150, a group holding a passing keypoint has g <= sqrt(R_g) (1 + 3u) up to roundings far
// below the slack, while a group is skipped only if g > 0 and g² > R_g (1 + 1e-8). A NaN or an
// infinity (in F, or the unbounded group of non-finite keypoints) makes that false: such
// groups are tested.
void SkipGroups(const GroupBounds& groups, int from, int to, const RowLine& line, double* skip) {
  const double l0 = line.l0, l1 = line.l1, l2 = line.l2;
  const double a = std::abs(l0), b = std::abs(l1);
  const double* __restrict cx = groups.centre_x.data();
  const double* __restrict cy = groups.centre_y.data();
  const double* __restrict hx = groups.half_x.data();
  const double* __restrict hy = groups.half_y.data();
  const double* __restrict most = groups.max_line1_norm2.data();
  double* __restrict out = skip;
  for (int c = from; c < to; ++c) {
    const double e = l0 * cx[c] + l1 * cy[c] + l2;
    const double g = std::abs(e) - ((a * hx[c] + b * hy[c]) * (1.0 + 1e-9) + line.absolute);
    const double r = line.max_sampson2 * (line.line2_norm2 + most[c]) * (1.0 + 1e-8);
    // g |g| - r > 0 iff g > 0 and g² > r (r >= 0; NaN: false). A double, not a flag: GCC
    // vectorises no comparison of doubles into an integer array.
    out[c] = g * std::abs(g) - r;
  }
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
  const EpipolarGrid grid = MakeEpipolarGrid(keypoints2, F);
  const double max_sampson2 = options.max_sampson_px * options.max_sampson_px;
  // Image 2's descriptors in the grid's order, and the rows by cells of image 1: nearby rows
  // have nearby lines, which meet the same cells, whose descriptors are then still in cache.
  DescriptorMatrix grid_descriptors2(n2, 128);
  for (int k = 0; k < n2; ++k) grid_descriptors2.row(k) = descriptors2.row(grid.index[k]);
  std::vector<char> finite1(n1);
  for (int i = 0; i < n1; ++i) {
    finite1[i] = std::isfinite(keypoints1[i].x()) && std::isfinite(keypoints1[i].y());
  }
  const std::vector<int> rows = SortByKey(MakeGridKeys(keypoints1, finite1));

  // The pairs are offered in another order than the plain loop's (ascending j in a row,
  // ascending i in a column): OfferUnordered ends in the same state.
  std::vector<Best2> best_for_1(n1);
  std::vector<Best2> best_for_2(n2);
  std::vector<double> skip_blocks(grid.block_begin.size()), skip_cells(grid.cell_begin.size());
  std::vector<int> candidates(n2);  // A row's, as positions in the grid's order.
  std::vector<float> distances(n2);
  const double* x = grid.x.data();
  const double* y = grid.y.data();
  const double* line1_norm2 = grid.line1_norm2.data();
  for (const int i : rows) {
    const Eigen::Vector3d line2 = F * keypoints1[i].homogeneous();
    const double line2_norm2 = line2.head<2>().squaredNorm();
    const RowLine line = MakeRowLine(line2, line2_norm2, max_sampson2, grid);
    const int num_blocks = static_cast<int>(grid.block_begin.size()) - 1;
    SkipGroups(grid.blocks, 0, num_blocks, line, skip_blocks.data());
    int num_candidates = 0;
    for (int b = 0; b < num_blocks; ++b) {
      if (skip_blocks[b] > 0.0) continue;
      SkipGroups(grid.cells, grid.block_begin[b], grid.block_begin[b + 1], line, skip_cells.data());
      for (int c = grid.block_begin[b]; c < grid.block_begin[b + 1]; ++c) {
        if (skip_cells[c] > 0.0) continue;
        for (int k = grid.cell_begin[c]; k < grid.cell_begin[c + 1]; ++k) {
          const double e = line.l0 * x[k] + line.l1 * y[k] + line.l2;  // line2.dot(x2 (x, y, 1))
          const double denominator = line2_norm2 + line1_norm2[k];
          // Branch-free: about one in six of these keypoints passes.
          candidates[num_candidates] = k;
          num_candidates += static_cast<int>(e * e <= max_sampson2 * denominator);
        }
      }
    }
    // Unit-norm descriptors: |a - b|² = 2 - 2 a·b. All of the row's first, then the offers
    // (independent products, which the processor overlaps).
    const auto d1 = descriptors1.row(i);
    for (int m = 0; m < num_candidates; ++m) {
      distances[m] = std::max(0.0f, 2.0f - 2.0f * d1.dot(grid_descriptors2.row(candidates[m])));
    }
    for (int m = 0; m < num_candidates; ++m) {
      const int j = grid.index[candidates[m]];
      best_for_1[i].OfferUnordered(distances[m], j);
      best_for_2[j].OfferUnordered(distances[m], i);
    }
  }

  std::vector<int> nearest_to_2(n2);
  for (int j = 0; j < n2; ++j) nearest_to_2[j] = best_for_2[j].index;
  return SelectMatches(best_for_1, nearest_to_2, options.max_distance, options.max_ratio,
                       options.cross_check);
}

}  // namespace reconduit
