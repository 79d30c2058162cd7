#include "core/texture/face_labeling.h"

#include "core/texture/rasterize.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <tuple>
#include <utility>

namespace reconduit {
namespace {

using texture_internal::ProjectChecked;
using texture_internal::RasterizeTriangle;

struct ViewCandidates {
  std::vector<std::pair<int, float>> faces;  // (face, quality), increasing face.
};

// The z-buffer of one view: per pixel the smallest camera depth of the mesh, +inf where empty.
cv::Mat RenderDepth(const TriangleMesh& mesh,
                    const Camera& small,
                    const std::vector<Eigen::Vector3d>& in_cam,
                    const std::vector<std::optional<Eigen::Vector2d>>& pixels) {
  cv::Mat depth(small.height, small.width, CV_32FC1,
                cv::Scalar(std::numeric_limits<float>::infinity()));
  for (const Eigen::Vector3i& face : mesh.faces) {
    const auto& p0 = pixels[face[0]];
    const auto& p1 = pixels[face[1]];
    const auto& p2 = pixels[face[2]];
    if (!p0 || !p1 || !p2) continue;
    // 1 / z is affine in screen space; interpolate it and keep the nearest.
    const double w0 = 1.0 / in_cam[face[0]].z(), w1 = 1.0 / in_cam[face[1]].z(),
                 w2 = 1.0 / in_cam[face[2]].z();
    RasterizeTriangle(*p0, *p1, *p2, small.width, small.height,
                      [&](int x, int y, double b0, double b1, double b2) {
                        const float z = static_cast<float>(1.0 / (b0 * w0 + b1 * w1 + b2 * w2));
                        float& d = depth.at<float>(y, x);
                        if (z < d) d = z;
                      });
  }
  return depth;
}

// True when the camera-frame point is not behind the z-buffer's surface at its pixel.
bool PointVisible(const Camera& small,
                  const cv::Mat& depth,
                  const Eigen::Vector3d& point_in_cam,
                  double tolerance) {
  const auto pixel = ProjectChecked(small, point_in_cam);
  if (!pixel) return false;
  const int x = static_cast<int>(std::lround(pixel->x()));
  const int y = static_cast<int>(std::lround(pixel->y()));
  if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) return false;
  return point_in_cam.z() <= depth.at<float>(y, x) * (1.0 + tolerance);
}

ViewCandidates ViewFaceCandidates(const TriangleMesh& mesh,
                                  const TextureView& view,
                                  const TextureOptions& options) {
  const Camera& camera = view.camera;
  const double scale =
      std::min(1.0, options.visibility_max_side / double(std::max(camera.width, camera.height)));
  const Camera small = camera.Scaled(scale);
  const std::size_t num_vertices = mesh.positions.size();
  std::vector<Eigen::Vector3d> in_cam(num_vertices);
  std::vector<std::optional<Eigen::Vector2d>> small_pixels(num_vertices), pixels(num_vertices);
  for (std::size_t i = 0; i < num_vertices; ++i) {
    in_cam[i] = view.cam_from_world * mesh.positions[i].cast<double>();
    small_pixels[i] = ProjectChecked(small, in_cam[i]);
    pixels[i] = ProjectChecked(camera, in_cam[i]);
  }
  const cv::Mat depth = RenderDepth(mesh, small, in_cam, small_pixels);
  const double min_cos = std::cos(options.max_view_angle_deg * M_PI / 180.0);

  ViewCandidates result;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[f];
    const auto& p0 = pixels[face[0]];
    const auto& p1 = pixels[face[1]];
    const auto& p2 = pixels[face[2]];
    if (!p0 || !p1 || !p2 || !camera.InImage(*p0) || !camera.InImage(*p1) || !camera.InImage(*p2)) {
      continue;
    }
    const Eigen::Vector3d& a = in_cam[face[0]];
    const Eigen::Vector3d& b = in_cam[face[1]];
    const Eigen::Vector3d& c = in_cam[face[2]];
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    const Eigen::Vector3d centroid = (a + b + c) / 3.0;
    const double normal_norm = normal.norm(), distance = centroid.norm();
    if (!(normal_norm > 0.0) || !(distance > 0.0)) continue;
    const double cos_angle = -normal.dot(centroid) / (normal_norm * distance);
    if (!(cos_angle >= min_cos)) continue;
    bool visible = PointVisible(small, depth, centroid, options.depth_tolerance);
    for (const Eigen::Vector3d* corner : {&a, &b, &c}) {
      if (!visible) break;
      visible = PointVisible(small, depth, 0.5 * (centroid + *corner), options.depth_tolerance);
    }
    if (!visible) continue;
    const Eigen::Vector2d e1 = *p1 - *p0, e2 = *p2 - *p0;
    const double area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    const double quality = area * cos_angle;
    if (quality > 0.0) result.faces.emplace_back(static_cast<int>(f), static_cast<float>(quality));
  }
  return result;
}

}  // namespace

FaceCandidates ComputeFaceCandidates(const TriangleMesh& mesh,
                                     const std::vector<TextureView>& views,
                                     const TextureOptions& options,
                                     Progress* progress,
                                     const CancelToken& cancel) {
  std::vector<ViewCandidates> per_view(views.size());
  ParallelFor(
      0, views.size(),
      [&](std::size_t v) {
        cancel.ThrowIfCanceled();
        per_view[v] = ViewFaceCandidates(mesh, views[v], options);
        if (progress != nullptr) progress->Advance();
      },
      options.num_threads);

  FaceCandidates candidates;
  candidates.offsets.assign(mesh.faces.size() + 1, 0);
  for (const ViewCandidates& view : per_view) {
    for (const auto& [face, quality] : view.faces) ++candidates.offsets[face + 1];
  }
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    candidates.offsets[f + 1] += candidates.offsets[f];
  }
  candidates.items.resize(candidates.offsets.back());
  std::vector<int> fill(candidates.offsets.begin(), candidates.offsets.end() - 1);
  for (std::size_t v = 0; v < per_view.size(); ++v) {  // Increasing views within each row.
    for (const auto& [face, quality] : per_view[v].faces) {
      candidates.items[fill[face]++] = {static_cast<int>(v), quality};
    }
  }
  return candidates;
}

FaceAdjacency ComputeFaceAdjacency(const TriangleMesh& mesh) {
  // (smaller vertex, larger vertex, face) per face edge, sorted: faces of one edge are adjacent.
  struct EdgeFace {
    int a, b, face;
  };
  std::vector<EdgeFace> edges;
  edges.reserve(3 * mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int u = mesh.faces[f][k], w = mesh.faces[f][(k + 1) % 3];
      edges.push_back({std::min(u, w), std::max(u, w), static_cast<int>(f)});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const EdgeFace& x, const EdgeFace& y) {
    return std::tie(x.a, x.b, x.face) < std::tie(y.a, y.b, y.face);
  });
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j].a == edges[i].a && edges[j].b == edges[i].b) ++j;
    for (std::size_t p = i; p < j; ++p) {
      for (std::size_t q = p + 1; q < j; ++q) {
        if (edges[p].face == edges[q].face) continue;
        pairs.emplace_back(edges[p].face, edges[q].face);
        pairs.emplace_back(edges[q].face, edges[p].face);
      }
    }
    i = j;
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  FaceAdjacency adjacency;
  adjacency.offsets.assign(mesh.faces.size() + 1, 0);
  adjacency.neighbors.reserve(pairs.size());
  for (const auto& [f, g] : pairs) {
    ++adjacency.offsets[f + 1];
    adjacency.neighbors.push_back(g);
  }
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    adjacency.offsets[f + 1] += adjacency.offsets[f];
  }
  return adjacency;
}

std::vector<int> SelectBestViews(const FaceCandidates& candidates) {
  const int num_faces = static_cast<int>(candidates.offsets.size()) - 1;
  std::vector<int> labels(num_faces, -1);
  for (int f = 0; f < num_faces; ++f) {
    float best = 0.0f;
    for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
      if (candidates.items[i].quality > best) {
        best = candidates.items[i].quality;
        labels[f] = candidates.items[i].view;
      }
    }
  }
  return labels;
}

namespace {

// D(f, view) = 1 - quality / best quality of f, or -1 when view is no candidate of f.
double DataCost(const FaceCandidates& candidates, int f, int view) {
  float best = 0.0f, mine = -1.0f;
  for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
    best = std::max(best, candidates.items[i].quality);
    if (candidates.items[i].view == view) mine = candidates.items[i].quality;
  }
  return mine < 0.0f ? -1.0 : 1.0 - mine / best;
}

// One sweep of iterated conditional modes; returns the faces that changed.
int IcmSweep(const FaceCandidates& candidates,
             const FaceAdjacency& adjacency,
             double smoothness_weight,
             std::vector<int>& label) {
  int changes = 0;
  for (int f = 0; f < static_cast<int>(label.size()); ++f) {
    if (label[f] < 0 || candidates.NumCandidates(f) < 2) continue;
    float best_quality = 0.0f;
    for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
      best_quality = std::max(best_quality, candidates.items[i].quality);
    }
    int best_label = label[f];
    double best_cost = std::numeric_limits<double>::infinity(), current_cost = best_cost;
    for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
      const FaceCandidate& candidate = candidates.items[i];
      double cost = 1.0 - candidate.quality / best_quality;
      for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
        const int other = label[adjacency.neighbors[n]];
        if (other >= 0 && other != candidate.view) cost += smoothness_weight;
      }
      if (candidate.view == label[f]) current_cost = cost;
      if (cost < best_cost) {
        best_cost = cost;
        best_label = candidate.view;
      }
    }
    // Only a strictly lower cost moves a face, so E decreases and sweeps cannot cycle.
    if (best_cost < current_cost - 1e-9 && best_label != label[f]) {
      label[f] = best_label;
      ++changes;
    }
  }
  return changes;
}

// One sweep of chart moves: each chart, smallest first, takes the label of a neighbouring
// chart when all its faces are candidates of that view and the energy drops:
//   dE = sum_{f in chart} (D(f, new) - D(f, old)) - weight * (border pairs with `new`).
// (No face outside a chart has the chart's label next to it: charts are components.) Charts
// next to a moved chart wait for the next sweep, whose charts are recomputed. Returns moves.
int ChartSweep(const FaceCandidates& candidates,
               const FaceAdjacency& adjacency,
               double smoothness_weight,
               std::vector<int>& label) {
  const Charts charts = ComputeCharts(label, adjacency);
  std::vector<int> order(charts.chart_view.size());
  for (std::size_t c = 0; c < order.size(); ++c) order[c] = static_cast<int>(c);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return charts.chart_faces[a].size() < charts.chart_faces[b].size();
  });
  std::vector<char> stale(order.size(), 0);
  int moves = 0;
  for (const int c : order) {
    if (stale[c]) continue;
    std::vector<std::pair<int, int>> border;  // (view, pairs), few entries.
    for (const int f : charts.chart_faces[c]) {
      for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
        const int other = label[adjacency.neighbors[n]];
        if (other < 0 || other == label[f]) continue;
        auto it = std::find_if(border.begin(), border.end(),
                               [&](const auto& entry) { return entry.first == other; });
        if (it == border.end())
          border.emplace_back(other, 1);
        else
          ++it->second;
      }
    }
    int best_view = -1;
    double best_delta = -1e-9;
    for (const auto& [view, pairs] : border) {
      double delta = -smoothness_weight * pairs;
      for (const int f : charts.chart_faces[c]) {
        const double cost = DataCost(candidates, f, view);
        if (cost < 0.0) {
          delta = std::numeric_limits<double>::infinity();
          break;
        }
        delta += cost - DataCost(candidates, f, label[f]);
      }
      if (delta < best_delta) {
        best_delta = delta;
        best_view = view;
      }
    }
    if (best_view < 0) continue;
    for (const int f : charts.chart_faces[c]) {
      label[f] = best_view;
      for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
        const int g = adjacency.neighbors[n];
        if (charts.face_chart[g] >= 0) stale[charts.face_chart[g]] = 1;
      }
    }
    ++moves;
  }
  return moves;
}

}  // namespace

int SmoothLabels(const FaceCandidates& candidates,
                 const FaceAdjacency& adjacency,
                 double smoothness_weight,
                 int max_sweeps,
                 std::vector<int>* labels) {
  THROW_CHECK_NOTNULL(labels);
  THROW_CHECK_EQ(candidates.offsets.size(), labels->size() + 1);
  int sweep = 0;
  while (sweep < max_sweeps) {
    ++sweep;
    if (IcmSweep(candidates, adjacency, smoothness_weight, *labels) > 0) continue;
    if (sweep >= max_sweeps) break;
    ++sweep;
    if (ChartSweep(candidates, adjacency, smoothness_weight, *labels) == 0) break;
  }
  return sweep;
}

Charts ComputeCharts(const std::vector<int>& labels, const FaceAdjacency& adjacency) {
  const int num_faces = static_cast<int>(labels.size());
  Charts charts;
  charts.face_chart.assign(num_faces, -1);
  std::vector<int> stack;
  for (int seed = 0; seed < num_faces; ++seed) {
    if (labels[seed] < 0 || charts.face_chart[seed] >= 0) continue;
    const int chart = static_cast<int>(charts.chart_view.size());
    charts.chart_view.push_back(labels[seed]);
    charts.chart_faces.emplace_back();
    charts.face_chart[seed] = chart;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const int f = stack.back();
      stack.pop_back();
      charts.chart_faces[chart].push_back(f);
      for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
        const int g = adjacency.neighbors[n];
        if (charts.face_chart[g] < 0 && labels[g] == labels[seed]) {
          charts.face_chart[g] = chart;
          stack.push_back(g);
        }
      }
    }
    std::sort(charts.chart_faces[chart].begin(), charts.chart_faces[chart].end());
  }
  return charts;
}

}  // namespace reconduit
