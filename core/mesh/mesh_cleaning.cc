#include "core/mesh/mesh_cleaning.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <meshoptimizer.h>
#include <numeric>
#include <utility>

namespace reconduit {
namespace {

// Keeps the faces whose `keep` is true.
void KeepFaces(TriangleMesh* mesh, const std::vector<bool>& keep) {
  std::size_t n = 0;
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    if (keep[f]) mesh->faces[n++] = mesh->faces[f];
  }
  mesh->faces.resize(n);
}

// Each face's undirected edges, sorted so that the faces of an edge are adjacent.
struct EdgeUse {
  std::pair<int, int> edge;
  std::uint32_t face;
  bool operator<(const EdgeUse& o) const { return edge != o.edge ? edge < o.edge : face < o.face; }
};

std::vector<EdgeUse> SortedEdges(const TriangleMesh& mesh) {
  std::vector<EdgeUse> edges;
  edges.reserve(3 * mesh.faces.size());
  for (std::uint32_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.faces[f][k], b = mesh.faces[f][(k + 1) % 3];
      edges.push_back({{std::min(a, b), std::max(a, b)}, f});
    }
  }
  std::sort(edges.begin(), edges.end());
  return edges;
}

// Calls fn(begin, end) for each run of uses of one edge.
template <typename Fn>
void ForEachEdge(const std::vector<EdgeUse>& edges, Fn fn) {
  for (std::size_t begin = 0; begin < edges.size();) {
    std::size_t end = begin + 1;
    while (end < edges.size() && edges[end].edge == edges[begin].edge) ++end;
    fn(begin, end);
    begin = end;
  }
}

std::size_t RemoveDegenerate(TriangleMesh* mesh) {
  std::vector<bool> keep(mesh->faces.size());
  std::size_t removed = 0;
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    const Eigen::Vector3i& t = mesh->faces[f];
    const Eigen::Vector3f& a = mesh->positions[t[0]];
    const bool repeated = t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
    keep[f] = !repeated && (mesh->positions[t[1]] - a).cross(mesh->positions[t[2]] - a).norm() > 0;
    removed += !keep[f];
  }
  KeepFaces(mesh, keep);
  return removed;
}

std::size_t RemoveDuplicates(TriangleMesh* mesh) {
  // Rotated so that the smallest index comes first: equal rotated triples face the same way.
  auto rotated = [](const Eigen::Vector3i& t) {
    const int k = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
    return std::array<int, 3>{t[k], t[(k + 1) % 3], t[(k + 2) % 3]};
  };
  std::vector<std::pair<std::array<int, 3>, std::uint32_t>> keyed;
  keyed.reserve(mesh->faces.size());
  for (std::uint32_t f = 0; f < mesh->faces.size(); ++f) {
    std::array<int, 3> key{mesh->faces[f][0], mesh->faces[f][1], mesh->faces[f][2]};
    std::sort(key.begin(), key.end());
    keyed.push_back({key, f});
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<bool> keep(mesh->faces.size(), true);
  std::size_t removed = 0;
  for (std::size_t begin = 0; begin < keyed.size();) {
    std::size_t end = begin + 1;
    while (end < keyed.size() && keyed[end].first == keyed[begin].first) ++end;
    if (end - begin > 1) {
      const auto first = rotated(mesh->faces[keyed[begin].second]);
      bool opposite = false;
      for (std::size_t k = begin + 1; k < end; ++k)
        opposite |= rotated(mesh->faces[keyed[k].second]) != first;
      for (std::size_t k = opposite ? begin : begin + 1; k < end; ++k) {
        keep[keyed[k].second] = false;
        ++removed;
      }
    }
    begin = end;
  }
  KeepFaces(mesh, keep);
  return removed;
}

std::size_t RemoveNonManifoldEdges(TriangleMesh* mesh) {
  const std::vector<EdgeUse> edges = SortedEdges(*mesh);
  std::vector<bool> keep(mesh->faces.size(), true);
  ForEachEdge(edges, [&](std::size_t begin, std::size_t end) {
    if (end - begin > 2) {
      for (std::size_t k = begin; k < end; ++k) keep[edges[k].face] = false;
    }
  });
  const std::size_t removed = std::count(keep.begin(), keep.end(), false);
  KeepFaces(mesh, keep);
  return removed;
}

std::uint32_t Find(std::vector<std::uint32_t>& parent, std::uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

void RemoveSmallComponents(TriangleMesh* mesh, double min_fraction, CleaningSummary* summary) {
  const std::vector<EdgeUse> edges = SortedEdges(*mesh);
  std::vector<std::uint32_t> parent(mesh->faces.size());
  std::iota(parent.begin(), parent.end(), 0u);
  ForEachEdge(edges, [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin + 1; k < end; ++k)
      parent[Find(parent, edges[k].face)] = Find(parent, edges[begin].face);
  });
  std::vector<std::size_t> size(mesh->faces.size(), 0);
  for (std::uint32_t f = 0; f < parent.size(); ++f) ++size[Find(parent, f)];
  const std::size_t largest = size.empty() ? 0 : *std::max_element(size.begin(), size.end());
  const double min_faces = min_fraction * static_cast<double>(largest);
  std::vector<bool> keep(mesh->faces.size());
  for (std::uint32_t f = 0; f < parent.size(); ++f) {
    const std::uint32_t root = Find(parent, f);
    keep[f] = size[root] >= min_faces;
    if (root == f) {
      ++summary->components;
      summary->removed_components += !keep[f];
    }
    summary->small_component_faces += !keep[f];
  }
  KeepFaces(mesh, keep);
}

}  // namespace

std::size_t RemoveUnusedVertices(TriangleMesh* mesh) {
  std::vector<int> remap(mesh->positions.size(), -1);
  for (const Eigen::Vector3i& t : mesh->faces) {
    for (int k = 0; k < 3; ++k) {
      THROW_CHECK(t[k] >= 0 && t[k] < static_cast<int>(remap.size())) << "vertex index " << t[k];
      remap[t[k]] = 0;
    }
  }
  int n = 0;
  for (std::size_t v = 0; v < remap.size(); ++v) {
    if (remap[v] < 0) continue;
    remap[v] = n;
    mesh->positions[n] = mesh->positions[v];
    if (!mesh->colors.empty()) mesh->colors[n] = mesh->colors[v];
    if (!mesh->normals.empty()) mesh->normals[n] = mesh->normals[v];
    ++n;
  }
  const std::size_t removed = mesh->positions.size() - n;
  mesh->positions.resize(n);
  if (!mesh->colors.empty()) mesh->colors.resize(n);
  if (!mesh->normals.empty()) mesh->normals.resize(n);
  for (Eigen::Vector3i& t : mesh->faces) t = Eigen::Vector3i(remap[t[0]], remap[t[1]], remap[t[2]]);
  return removed;
}

CleaningSummary CleanMesh(TriangleMesh* mesh, const CleaningOptions& options) {
  THROW_CHECK(mesh->texcoords.empty()) << "clean a mesh before texturing it";
  const int n = static_cast<int>(mesh->positions.size());
  for (const Eigen::Vector3i& t : mesh->faces)
    THROW_CHECK(t.minCoeff() >= 0 && t.maxCoeff() < n) << "face " << t.transpose();
  CleaningSummary summary;
  summary.degenerate_faces = RemoveDegenerate(mesh);
  summary.duplicate_faces = RemoveDuplicates(mesh);
  summary.non_manifold_faces = RemoveNonManifoldEdges(mesh);
  RemoveSmallComponents(mesh, options.min_component_fraction, &summary);
  summary.unused_vertices = RemoveUnusedVertices(mesh);
  return summary;
}

SimplificationSummary SimplifyMesh(TriangleMesh* mesh, std::size_t target_faces) {
  THROW_CHECK(mesh->texcoords.empty()) << "simplify a mesh before texturing it";
  SimplificationSummary summary;
  summary.faces_before = summary.faces_after = mesh->faces.size();
  if (mesh->faces.size() <= target_faces || mesh->positions.empty()) return summary;
  std::vector<unsigned int> indices(3 * mesh->faces.size());
  for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) indices[3 * f + k] = static_cast<unsigned int>(mesh->faces[f][k]);
  }
  std::vector<unsigned int> simplified(indices.size());
  float error = 0.0f;
  // No error bound (1 = the whole extent): the face count decides; quadrics choose where.
  const std::size_t count =
      meshopt_simplify(simplified.data(), indices.data(), indices.size(), mesh->positions[0].data(),
                       mesh->positions.size(), sizeof(Eigen::Vector3f), 3 * target_faces, 1.0f,
                       meshopt_SimplifyLockBorder, &error);
  mesh->faces.resize(count / 3);
  for (std::size_t f = 0; f < count / 3; ++f) {
    mesh->faces[f] =
        Eigen::Vector3i(simplified[3 * f], simplified[3 * f + 1], simplified[3 * f + 2]);
  }
  // Collapses along a locked straight border can leave slivers of zero area.
  RemoveDegenerate(mesh);
  RemoveUnusedVertices(mesh);
  summary.faces_after = mesh->faces.size();
  summary.relative_error = error;
  return summary;
}

void ComputeVertexNormals(TriangleMesh* mesh) {
  mesh->normals.assign(mesh->positions.size(), Eigen::Vector3f::Zero());
  for (const Eigen::Vector3i& t : mesh->faces) {
    const Eigen::Vector3f& a = mesh->positions[t[0]];
    // Twice the area times the unit normal: area weighting for free.
    const Eigen::Vector3f n = (mesh->positions[t[1]] - a).cross(mesh->positions[t[2]] - a);
    for (int k = 0; k < 3; ++k) mesh->normals[t[k]] += n;
  }
  for (Eigen::Vector3f& n : mesh->normals) {
    const float norm = n.norm();
    if (norm > 0) n /= norm;
  }
}

}  // namespace reconduit
