#include "core/mvs/cloud_distance.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>

namespace reconduit {
namespace {

using CellKey = std::int64_t;

// 21 bits per axis around the cloud's first point: +-1 M cells of the radius.
CellKey KeyOf(const Eigen::Vector3i& cell) {
  constexpr std::int64_t kHalf = 1 << 20;
  auto part = [&](int c) {
    return static_cast<std::int64_t>(std::clamp<std::int64_t>(c + kHalf, 0, 2 * kHalf - 1));
  };
  return (part(cell.x()) << 42) | (part(cell.y()) << 21) | part(cell.z());
}

}  // namespace

std::vector<double> NearestDistancesWithin(const std::vector<Eigen::Vector3f>& cloud,
                                           const std::vector<Eigen::Vector3d>& queries,
                                           double radius) {
  THROW_CHECK_GT(radius, 0.0);
  std::vector<double> distances(queries.size(), std::numeric_limits<double>::infinity());
  if (cloud.empty()) return distances;
  const Eigen::Vector3d origin = cloud.front().cast<double>();
  auto cell_of = [&](const Eigen::Vector3d& p) -> Eigen::Vector3i {
    return ((p - origin) / radius).array().floor().cast<int>();
  };
  std::vector<std::pair<CellKey, std::uint32_t>> sorted(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
    sorted[i] = {KeyOf(cell_of(cloud[i].cast<double>())), static_cast<std::uint32_t>(i)};
  std::sort(sorted.begin(), sorted.end());

  for (std::size_t q = 0; q < queries.size(); ++q) {
    const Eigen::Vector3i centre = cell_of(queries[q]);
    double best_sq = radius * radius;
    bool found = false;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const CellKey key = KeyOf(centre + Eigen::Vector3i(dx, dy, dz));
          auto it =
              std::lower_bound(sorted.begin(), sorted.end(), std::make_pair(key, std::uint32_t{0}));
          for (; it != sorted.end() && it->first == key; ++it) {
            const double d_sq = (cloud[it->second].cast<double>() - queries[q]).squaredNorm();
            if (d_sq <= best_sq) {
              best_sq = d_sq;
              found = true;
            }
          }
        }
      }
    }
    if (found) distances[q] = std::sqrt(best_sq);
  }
  return distances;
}

double Median(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace reconduit
