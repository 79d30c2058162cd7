#include "core/mvs/view_selection.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <utility>

namespace reconduit {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// What one reference image knows about one candidate neighbour.
struct PairEvidence {
  double score = 0.0;
  std::vector<double> angles_deg;
  std::vector<double> scale_ratios;
};

// Per image: camera centre, pose and focal, looked up once.
struct ViewGeometry {
  Eigen::Vector3d center;
  const Rigid3d* cam_from_world = nullptr;
  double focal = 0.0;
};

double ScaleWeight(double ratio) {
  if (ratio > 1.0) return 1.0 / ratio;  // The neighbour is coarser.
  if (ratio < 0.5) return 2.0 * ratio;  // Much finer: its detail is averaged away.
  return 1.0;
}

}  // namespace

bool ViewSelectionOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (max_neighbors < 1 || max_neighbors > 32) {
    m << "max_neighbors must be in [1, 32], got " << max_neighbors;
  } else if (min_shared_points < 1 || min_shared_points > 10000) {
    m << "min_shared_points must be in [1, 10000], got " << min_shared_points;
  } else if (!(min_triangulation_angle_deg > 0.0 &&
               min_triangulation_angle_deg <= ideal_triangulation_angle_deg &&
               ideal_triangulation_angle_deg <= max_triangulation_angle_deg &&
               max_triangulation_angle_deg <= 90.0)) {
    m << "triangulation angles must satisfy 0 < min <= ideal <= max <= 90, got "
      << min_triangulation_angle_deg << ", " << ideal_triangulation_angle_deg << ", "
      << max_triangulation_angle_deg;
  } else if (!(min_relative_score >= 0.0 && min_relative_score <= 1.0)) {
    m << "min_relative_score must be in [0, 1], got " << min_relative_score;
  }
  if (error) *error = m.str();
  return m.str().empty();
}

std::map<int, std::vector<ViewNeighbor>> SelectViews(const Reconstruction& model,
                                                     const ViewSelectionOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  std::map<int, ViewGeometry> views;
  for (const auto& [id, image] : model.images) {
    views[id] = {image.cam_from_world.CenterInWorld(), &image.cam_from_world,
                 model.cameras.at(image.camera_id).focal};
  }

  constexpr double kDegPerRad = 180.0 / std::numbers::pi;
  std::map<std::pair<int, int>, PairEvidence> evidence;  // (reference, neighbour)
  for (const auto& [point_id, point] : model.points) {
    const Eigen::Vector3d& x = point.xyz_in_world;
    for (std::size_t a = 0; a < point.observations.size(); ++a) {
      const ViewGeometry& ref = views.at(point.observations[a].image_id);
      const double ref_depth = (*ref.cam_from_world * x).z();
      if (ref_depth <= 0.0) continue;
      for (std::size_t b = 0; b < point.observations.size(); ++b) {
        if (a == b || point.observations[a].image_id == point.observations[b].image_id) continue;
        const ViewGeometry& src = views.at(point.observations[b].image_id);
        const double src_depth = (*src.cam_from_world * x).z();
        if (src_depth <= 0.0) continue;
        const Eigen::Vector3d ray_ref = (ref.center - x).normalized();
        const Eigen::Vector3d ray_src = (src.center - x).normalized();
        const double angle = std::acos(std::clamp(ray_ref.dot(ray_src), -1.0, 1.0)) * kDegPerRad;
        if (angle < options.min_triangulation_angle_deg ||
            angle > options.max_triangulation_angle_deg) {
          continue;
        }
        const double ratio = (src_depth / src.focal) / (ref_depth / ref.focal);
        const double w_angle =
            std::pow(std::min(angle / options.ideal_triangulation_angle_deg, 1.0), 2.0);
        PairEvidence& e =
            evidence[{point.observations[a].image_id, point.observations[b].image_id}];
        e.score += w_angle * ScaleWeight(ratio);
        e.angles_deg.push_back(angle);
        e.scale_ratios.push_back(ratio);
      }
    }
  }

  std::map<int, std::vector<ViewNeighbor>> result;
  for (const auto& [id, view] : views) result[id];
  for (auto& [key, e] : evidence) {
    if (static_cast<int>(e.angles_deg.size()) < options.min_shared_points) continue;
    ViewNeighbor n;
    n.image_id = key.second;
    n.score = e.score;
    n.shared_points = static_cast<int>(e.angles_deg.size());
    n.median_angle_deg = Median(std::move(e.angles_deg));
    n.median_scale_ratio = Median(std::move(e.scale_ratios));
    result[key.first].push_back(n);
  }
  for (auto& [id, neighbors] : result) {
    std::sort(neighbors.begin(), neighbors.end(), [](const ViewNeighbor& a, const ViewNeighbor& b) {
      return a.score != b.score ? a.score > b.score : a.image_id < b.image_id;
    });
    if (neighbors.empty()) continue;
    const double cut = options.min_relative_score * neighbors.front().score;
    std::erase_if(neighbors, [&](const ViewNeighbor& n) { return n.score < cut; });
    if (static_cast<int>(neighbors.size()) > options.max_neighbors)
      neighbors.resize(options.max_neighbors);
  }
  return result;
}

}  // namespace reconduit
