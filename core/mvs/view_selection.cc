#include "core/mvs/view_selection.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <unordered_map>
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
  // The shared points counted, with their weight w_angle * w_scale.
  std::vector<std::pair<int, double>> points;
};

using EvidenceMap = std::map<std::pair<int, int>, PairEvidence>;  // (reference, neighbour)

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

// What choosing `candidate` as a further source of `reference` adds, given how many chosen
// sources see each point (view_selection.h: 1 for an unseen point, w 2^-c for one seen c times).
double CoverageGain(const PairEvidence& candidate, const std::unordered_map<int, int>& times_seen) {
  double gain = 0.0;
  for (const auto& [point_id, weight] : candidate.points) {
    const auto it = times_seen.find(point_id);
    const int c = it == times_seen.end() ? 0 : it->second;
    gain += c == 0 ? 1.0 : weight * std::ldexp(1.0, -c);
  }
  return gain;
}

// Reorders `neighbors` (best score first) so that its first `count` are chosen greedily for
// coverage of `reference` (view_selection.h); the rest keep their order.
void OrderForCoverage(int reference,
                      int count,
                      const EvidenceMap& evidence,
                      std::vector<ViewNeighbor>* neighbors) {
  const int n = static_cast<int>(neighbors->size());
  count = std::min(count, n);
  if (count <= 1) return;
  std::unordered_map<int, int> times_seen;  // Point id -> chosen sources that see it.
  std::vector<bool> chosen(n, false);
  std::vector<ViewNeighbor> order;
  for (int pick = 0; pick < count; ++pick) {
    int best = -1;
    double best_gain = -1.0;
    for (int k = 0; k < n && pick > 0; ++k) {
      if (chosen[k]) continue;
      const double gain =
          CoverageGain(evidence.at({reference, (*neighbors)[k].image_id}), times_seen);
      if (gain > best_gain) best = k, best_gain = gain;  // Ties: the better scored.
    }
    if (pick == 0) best = 0;  // The best-scored neighbour first.
    chosen[best] = true;
    order.push_back((*neighbors)[best]);
    for (const auto& entry : evidence.at({reference, (*neighbors)[best].image_id}).points)
      ++times_seen[entry.first];
  }
  for (int k = 0; k < n; ++k)
    if (!chosen[k]) order.push_back((*neighbors)[k]);
  *neighbors = std::move(order);
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
  } else if (coverage_sources < 0 || coverage_sources > 32) {
    m << "coverage_sources must be in [0, 32], got " << coverage_sources;
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
  EvidenceMap evidence;
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
        e.points.emplace_back(point_id, w_angle * ScaleWeight(ratio));
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
    OrderForCoverage(id, std::min(options.coverage_sources, options.max_neighbors), evidence,
                     &neighbors);
    if (static_cast<int>(neighbors.size()) > options.max_neighbors)
      neighbors.resize(options.max_neighbors);
  }
  return result;
}

}  // namespace reconduit
