#include "core/estimators/normalization.h"

#include "core/util/logging.h"

#include <cmath>

namespace reconduit {

bool CenterAndNormalizeImagePoints(const std::vector<Eigen::Vector2d>& points,
                                   std::vector<Eigen::Vector2d>* normalized_points,
                                   Eigen::Matrix3d* normalized_from_original) {
  THROW_CHECK_NOTNULL(normalized_points);
  THROW_CHECK_NOTNULL(normalized_from_original);
  if (points.empty()) return false;

  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  if (!centroid.allFinite()) return false;

  double mean_distance = 0.0;
  for (const auto& p : points) mean_distance += (p - centroid).norm();
  mean_distance /= static_cast<double>(points.size());
  // Coincident points: no scale can be defined. The threshold is relative so that it works
  // for pixels as well as for normalised camera coordinates.
  if (!std::isfinite(mean_distance) || mean_distance <= 1e-12 * centroid.norm() + 1e-300) {
    return false;
  }

  const double scale = std::sqrt(2.0) / mean_distance;
  Eigen::Matrix3d& T = *normalized_from_original;
  T << scale, 0.0, -scale * centroid.x(), 0.0, scale, -scale * centroid.y(), 0.0, 0.0, 1.0;
  normalized_points->resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    (*normalized_points)[i] = scale * (points[i] - centroid);
  }
  return true;
}

}  // namespace reconduit
