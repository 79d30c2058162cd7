#include "core/mesh/surface_reconstruction.h"

#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <Eigen/Geometry>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <maxflow/graph.h>
#include <tuple>
#include <utility>

namespace reconduit {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_3<std::uint32_t, Kernel>;
using CellBase = CGAL::Triangulation_cell_base_with_info_3<std::uint32_t, Kernel>;
using Tds = CGAL::Triangulation_data_structure_3<VertexBase, CellBase>;
using Delaunay = CGAL::Delaunay_triangulation_3<Kernel, Tds>;
using CgalPoint = Kernel::Point_3;
using VertexHandle = Delaunay::Vertex_handle;
using CellHandle = Delaunay::Cell_handle;
// One of the instantiations libmaxflow ships (instances.inc).
using FlowGraph = maxflow::Graph<float, float, float>;

// Points per ParallelFor item in the walks (one item per point would spend more time handing
// items out than walking).
constexpr std::size_t kWalkChunk = 2048;

CgalPoint ToCgal(const Eigen::Vector3d& p) { return CgalPoint(p.x(), p.y(), p.z()); }
Eigen::Vector3d FromCgal(const CgalPoint& p) { return {p.x(), p.y(), p.z()}; }

// The kept points of step 1: for each, the index of its representative in the cloud and the
// union of the visibility of the points it stands for.
struct KeptPoints {
  std::vector<std::uint32_t> source;
  std::vector<std::uint32_t> visibility_offsets{0};
  std::vector<int> visibility;
  std::vector<float> footprint;  // Of the representative.
  std::size_t size() const { return source.size(); }
};

// Step 1. A multi-level grid: a point falls into the cell of side 2^level containing it, level
// = floor(log2(footprint * spacing)), so that the cell side is between one and two spacings.
KeptPoints DecimatePoints(const DenseCloud& cloud,
                          const std::vector<float>& footprints,
                          double spacing_px) {
  using Key = std::tuple<int, std::int64_t, std::int64_t, std::int64_t>;
  std::vector<std::pair<Key, std::uint32_t>> keyed;
  keyed.reserve(cloud.size());
  for (std::uint32_t i = 0; i < cloud.size(); ++i) {
    if (!(footprints[i] > 0.0f)) continue;
    const int level = static_cast<int>(std::floor(std::log2(footprints[i] * spacing_px)));
    const double side = std::ldexp(1.0, level);
    const Eigen::Vector3f& p = cloud.positions[i];
    keyed.push_back({{level, static_cast<std::int64_t>(std::floor(p.x() / side)),
                      static_cast<std::int64_t>(std::floor(p.y() / side)),
                      static_cast<std::int64_t>(std::floor(p.z() / side))},
                     i});
  }
  auto views_of = [&](std::uint32_t i) {
    return cloud.visibility_offsets[i + 1] - cloud.visibility_offsets[i];
  };
  // Within a cell: the point seen by most photos first, then the lowest index (deterministic).
  std::sort(keyed.begin(), keyed.end(), [&](const auto& a, const auto& b) {
    if (a.first != b.first) return a.first < b.first;
    if (views_of(a.second) != views_of(b.second)) return views_of(a.second) > views_of(b.second);
    return a.second < b.second;
  });
  KeptPoints kept;
  std::vector<int> ids;
  for (std::size_t begin = 0; begin < keyed.size();) {
    std::size_t end = begin + 1;
    while (end < keyed.size() && keyed[end].first == keyed[begin].first) ++end;
    ids.clear();
    for (std::size_t k = begin; k < end; ++k) {
      const std::uint32_t i = keyed[k].second;
      ids.insert(ids.end(), cloud.visibility.begin() + cloud.visibility_offsets[i],
                 cloud.visibility.begin() + cloud.visibility_offsets[i + 1]);
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    kept.source.push_back(keyed[begin].second);
    kept.footprint.push_back(footprints[keyed[begin].second]);
    kept.visibility.insert(kept.visibility.end(), ids.begin(), ids.end());
    kept.visibility_offsets.push_back(kept.visibility.size());
    begin = end;
  }
  return kept;
}

// The weights of steps 3 and 4, indexed by the cells' info(): facet[4 * c + k] is the number
// of lines of sight entering cell c through its facet k (from the neighbour across it).
struct Evidence {
  explicit Evidence(std::size_t cells) : facet(4 * cells, 0.0f), source(cells), sink(cells) {}
  std::vector<float> facet, source, sink;
  static void Add(float& weight) { std::atomic_ref<float>(weight).fetch_add(1.0f); }
};

// Step 3 for one line of sight: walks from the point's vertex `v` to `camera`, then marks the
// cell `sink_distance` behind the point. Returns the number of facets crossed.
std::uint64_t WalkLineOfSight(const Delaunay& dt,
                              VertexHandle v,
                              const Eigen::Vector3d& camera,
                              double footprint,
                              double sink_distance,
                              Evidence* evidence) {
  const Eigen::Vector3d p = FromCgal(v->point());
  const Eigen::Vector3d to_camera = (camera - p).normalized();
  // The walk starts a hair in front of the point, inside the tetrahedron of the point's star
  // that the line of sight leaves it through: started at the vertex itself, the traverser may
  // begin in any tetrahedron of the star and charge a facet the line never crosses.
  const Eigen::Vector3d start = p + 1e-3 * footprint * to_camera;
  std::uint64_t crossed = 0;
  auto it = dt.segment_traverser_cells_begin(ToCgal(start), ToCgal(camera), v->cell());
  const auto end = dt.segment_traverser_cells_end();
  CellHandle previous = it;
  // A point on the convex hull seen from outside it starts in an infinite cell: nothing to walk.
  if (dt.is_infinite(previous)) {
    it = end;
  } else {
    ++it;
  }
  for (; it != end; ++it) {
    const CellHandle cell = it;
    int k = -1;
    // The walk may pass through an edge or a vertex; then consecutive cells share no facet and
    // there is no facet to weigh.
    if (previous->has_neighbor(cell, k)) {
      Evidence::Add(evidence->facet[4 * previous->info() + k]);
      ++crossed;
    }
    previous = cell;
    if (dt.is_infinite(cell)) break;  // Left the convex hull: the camera is outside it.
  }
  Evidence::Add(evidence->source[previous->info()]);

  const Eigen::Vector3d behind = p - sink_distance * to_camera;
  const CellHandle inside = dt.locate(ToCgal(behind), v->cell());
  Evidence::Add(evidence->sink[inside->info()]);
  return crossed;
}

// Steps 3 and 4: the inside/outside label of every cell (by info()).
std::vector<bool> LabelCells(const Delaunay& dt,
                             const Evidence& evidence,
                             std::size_t num_cells,
                             SurfaceSummary* summary) {
  FlowGraph graph(static_cast<int>(num_cells), static_cast<int>(2 * num_cells));
  graph.add_node(static_cast<int>(num_cells));
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
    const std::uint32_t i = c->info();
    if (evidence.source[i] > 0 || evidence.sink[i] > 0)
      graph.add_tweights(i, evidence.source[i], evidence.sink[i]);
    for (int k = 0; k < 4; ++k) {
      const CellHandle n = c->neighbor(k);
      const std::uint32_t j = n->info();
      if (j < i) continue;  // Each facet once.
      const int back = n->index(c);
      // i -> j: lines of sight entering j from i; j -> i: entering i from j.
      graph.add_edge(i, j, evidence.facet[4 * j + back], evidence.facet[4 * i + k]);
    }
  }
  graph.maxflow();
  std::vector<bool> inside(num_cells);
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
    // Cells the evidence leaves free (in neither search tree): finite ones are inside, the
    // infinite ones outside, so that a convex hull facet seen by no line of sight still bounds
    // the model (the facets on the far side of the data are removed by ExtractSurface).
    const std::uint32_t i = c->info();
    const auto free_label = dt.is_infinite(c) ? FlowGraph::SOURCE : FlowGraph::SINK;
    inside[i] = graph.what_segment(static_cast<int>(i), free_label) == FlowGraph::SINK;
    summary->inside_cells += inside[i];
  }
  return inside;
}

// Makes the labelling manifold along edges: around an edge, the cells alternate between
// inside and outside at most twice, or the edge would have four or more faces (two inside
// regions touching along it). Where they alternate more, the shortest run of inside cells
// around the edge becomes outside (carved), which removes that contact and its faces; repeated
// until nothing changes or after `max_rounds`. Returns the number of cells relabelled.
std::size_t MakeEdgesManifold(const Delaunay& dt, std::vector<bool>* inside, int max_rounds = 4) {
  std::size_t flipped = 0;
  std::vector<CellHandle> around;
  for (int round = 0; round < max_rounds; ++round) {
    std::size_t flipped_now = 0;
    for (auto e = dt.finite_edges_begin(); e != dt.finite_edges_end(); ++e) {
      around.clear();
      auto c = dt.incident_cells(*e), done = c;
      do around.push_back(c);
      while (++c != done);
      const std::size_t n = around.size();
      int changes = 0;
      for (std::size_t k = 0; k < n; ++k)
        changes += (*inside)[around[k]->info()] != (*inside)[around[(k + 1) % n]->info()];
      if (changes <= 2) continue;
      // Runs of inside cells, starting after an outside cell.
      std::size_t start = 0;
      while ((*inside)[around[start]->info()]) ++start;
      std::size_t best_begin = 0, best_length = n + 1;
      for (std::size_t k = 1; k <= n;) {
        if (!(*inside)[around[(start + k) % n]->info()]) {
          ++k;
          continue;
        }
        std::size_t length = 0;
        while (k + length <= n && (*inside)[around[(start + k + length) % n]->info()]) ++length;
        if (length < best_length) {
          best_length = length;
          best_begin = start + k;
        }
        k += length;
      }
      for (std::size_t k = 0; k < best_length; ++k)
        (*inside)[around[(best_begin + k) % n]->info()] = false;
      flipped_now += best_length;
    }
    flipped += flipped_now;
    if (flipped_now == 0) break;
  }
  return flipped;
}

// Whether any photo that saw one of a face's corners sees the face from its front (the outside
// of the model).
bool SeenFromItsFront(const KeptPoints& kept,
                      const std::vector<SurfaceView>& views,
                      std::array<std::uint32_t, 3> corners,
                      const Eigen::Vector3d& centroid,
                      const Eigen::Vector3d& normal) {
  for (std::uint32_t k : corners) {
    for (std::uint32_t j = kept.visibility_offsets[k]; j < kept.visibility_offsets[k + 1]; ++j) {
      if (normal.dot(views[kept.visibility[j]].center - centroid) > 0) return true;
    }
  }
  return false;
}

// Steps 5 and 6.
TriangleMesh ExtractSurface(const Delaunay& dt,
                            const std::vector<bool>& inside,
                            const DenseCloud& cloud,
                            const KeptPoints& kept,
                            const std::vector<SurfaceView>& views,
                            double max_edge_px,
                            SurfaceSummary* summary) {
  std::vector<int> vertex_of_point(kept.size(), -1);
  TriangleMesh mesh;
  auto vertex = [&](VertexHandle v) {
    const std::uint32_t k = v->info();
    if (vertex_of_point[k] < 0) {
      vertex_of_point[k] = static_cast<int>(mesh.positions.size());
      mesh.positions.push_back(cloud.positions[kept.source[k]]);
      mesh.colors.push_back(cloud.colors[kept.source[k]]);
    }
    return vertex_of_point[k];
  };
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) {
    if (!inside[c->info()]) continue;
    for (int k = 0; k < 4; ++k) {
      if (inside[c->neighbor(k)->info()]) continue;
      ++summary->cut_faces;
      VertexHandle a = c->vertex((k + 1) & 3), b = c->vertex((k + 2) & 3),
                   d = c->vertex((k + 3) & 3);
      const Eigen::Vector3d pa = FromCgal(a->point()), pb = FromCgal(b->point()),
                            pd = FromCgal(d->point());
      const double longest =
          std::max({(pa - pb).squaredNorm(), (pb - pd).squaredNorm(), (pd - pa).squaredNorm()});
      const double footprint = std::max(
          {kept.footprint[a->info()], kept.footprint[b->info()], kept.footprint[d->info()]});
      if (longest > std::pow(max_edge_px * footprint, 2)) {
        ++summary->trimmed_faces;
        continue;
      }
      // Normal away from the cell's fourth vertex, i.e. towards the outside.
      Eigen::Vector3d normal = (pb - pa).cross(pd - pa);
      if (normal.dot(FromCgal(c->vertex(k)->point()) - pa) > 0) {
        std::swap(b, d);
        normal = -normal;
      }
      if (!SeenFromItsFront(kept, views, {a->info(), b->info(), d->info()}, (pa + pb + pd) / 3,
                            normal)) {
        ++summary->unseen_faces;
        continue;
      }
      mesh.faces.emplace_back(vertex(a), vertex(b), vertex(d));
    }
  }
  return mesh;
}

}  // namespace

bool SurfaceOptions::Check(std::string* error) const {
  auto fail = [&](const char* what) {
    if (error) *error = what;
    return false;
  };
  if (!(point_spacing_px >= 0.5 && point_spacing_px <= 50))
    return fail("point_spacing_px must be in [0.5, 50]");
  if (max_rays_per_point < 1 || max_rays_per_point > 64)
    return fail("max_rays_per_point must be in [1, 64]");
  if (!(sink_distance_px >= 0.1 && sink_distance_px <= 1000))
    return fail("sink_distance_px must be in [0.1, 1000]");
  if (!(max_edge_px >= 2 && max_edge_px <= 10000)) return fail("max_edge_px must be in [2, 10000]");
  return true;
}

std::vector<float> PointFootprints(const DenseCloud& cloud, const std::vector<SurfaceView>& views) {
  for (const SurfaceView& view : views) THROW_CHECK(view.focal_px > 0) << view.focal_px;
  std::vector<float> footprints(cloud.size(), 0.0f);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (std::uint32_t k = cloud.visibility_offsets[i]; k < cloud.visibility_offsets[i + 1]; ++k) {
      const int id = cloud.visibility[k];
      THROW_CHECK(id >= 0 && id < static_cast<int>(views.size())) << "visibility id " << id;
      const SurfaceView& view = views[id];
      best =
          std::min(best, (cloud.positions[i].cast<double>() - view.center).norm() / view.focal_px);
    }
    if (std::isfinite(best)) footprints[i] = static_cast<float>(best);
  }
  return footprints;
}

SurfaceResult ReconstructSurface(const DenseCloud& cloud,
                                 const std::vector<SurfaceView>& views,
                                 const SurfaceOptions& options,
                                 Progress* progress,
                                 const CancelToken& cancel) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  SurfaceResult result;
  SurfaceSummary& summary = result.summary;
  summary.input_points = cloud.size();
  Timer timer;
  const KeptPoints kept =
      DecimatePoints(cloud, PointFootprints(cloud, views), options.point_spacing_px);
  summary.seconds_decimation = timer.ElapsedSeconds();
  cancel.ThrowIfCanceled();
  if (kept.size() < 4) return result;

  timer.Restart();
  std::vector<std::pair<CgalPoint, std::uint32_t>> input;
  input.reserve(kept.size());
  for (std::uint32_t k = 0; k < kept.size(); ++k)
    input.emplace_back(ToCgal(cloud.positions[kept.source[k]].cast<double>()), k);
  Delaunay dt(input.begin(), input.end());
  input = {};
  if (dt.dimension() < 3) return result;
  std::vector<VertexHandle> vertex_of(kept.size());
  for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v)
    vertex_of[v->info()] = v;
  std::uint32_t num_cells = 0;
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) c->info() = num_cells++;
  summary.kept_points = dt.number_of_vertices();
  summary.cells = num_cells;
  summary.seconds_delaunay = timer.ElapsedSeconds();
  LOG_INFO << "surface: " << cloud.size() << " points, " << kept.size() << " kept, "
           << summary.kept_points << " vertices, " << num_cells << " tetrahedra in "
           << summary.seconds_decimation + summary.seconds_delaunay << " s";
  cancel.ThrowIfCanceled();

  timer.Restart();
  Evidence evidence(num_cells);
  const std::size_t chunks = (kept.size() + kWalkChunk - 1) / kWalkChunk;
  if (progress) progress->Restart(chunks, "lines of sight through the tetrahedra");
  std::atomic<std::uint64_t> crossed{0}, rays{0};
  ParallelFor(
      0, chunks,
      [&](std::size_t chunk) {
        cancel.ThrowIfCanceled();
        std::uint64_t local_crossed = 0, local_rays = 0;
        std::vector<std::pair<double, int>> nearest;
        for (std::size_t k = chunk * kWalkChunk;
             k < std::min(kept.size(), (chunk + 1) * kWalkChunk); ++k) {
          const VertexHandle v = vertex_of[k];
          if (v == VertexHandle()) continue;  // Same position as another kept point.
          const Eigen::Vector3d p = FromCgal(v->point());
          nearest.clear();
          for (std::uint32_t j = kept.visibility_offsets[k]; j < kept.visibility_offsets[k + 1];
               ++j)
            nearest.emplace_back((views[kept.visibility[j]].center - p).squaredNorm(),
                                 kept.visibility[j]);
          std::sort(nearest.begin(), nearest.end());
          nearest.resize(std::min<std::size_t>(nearest.size(), options.max_rays_per_point));
          for (const auto& [distance, id] : nearest) {
            local_crossed +=
                WalkLineOfSight(dt, v, views[id].center, kept.footprint[k],
                                options.sink_distance_px * kept.footprint[k], &evidence);
            ++local_rays;
          }
        }
        crossed += local_crossed;
        rays += local_rays;
        if (progress) progress->Advance();
      },
      options.num_threads);
  summary.rays = rays;
  summary.facets_crossed = crossed;
  summary.seconds_visibility = timer.ElapsedSeconds();
  LOG_INFO << "surface: " << summary.rays << " lines of sight crossed " << summary.facets_crossed
           << " facets in " << summary.seconds_visibility << " s";
  cancel.ThrowIfCanceled();

  timer.Restart();
  std::vector<bool> inside = LabelCells(dt, evidence, num_cells, &summary);
  summary.relabelled_cells = MakeEdgesManifold(dt, &inside);
  summary.seconds_cut = timer.ElapsedSeconds();
  cancel.ThrowIfCanceled();

  timer.Restart();
  result.mesh = ExtractSurface(dt, inside, cloud, kept, views, options.max_edge_px, &summary);
  summary.seconds_extraction = timer.ElapsedSeconds();
  LOG_INFO << "surface: " << summary.inside_cells << " of " << num_cells << " tetrahedra inside, "
           << summary.relabelled_cells << " carved for manifold edges (" << summary.seconds_cut
           << " s), " << summary.cut_faces << " faces on the cut, " << summary.trimmed_faces
           << " trimmed, " << summary.unseen_faces << " seen from behind only, "
           << result.mesh.NumFaces() << " kept";
  if (progress) progress->Finish();
  return result;
}

}  // namespace reconduit
