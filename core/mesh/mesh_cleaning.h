// Cleaning and simplification of a reconstructed surface, and its vertex normals.
//
// CleanMesh removes, in this order:
//  - degenerate faces (a repeated vertex, or zero area),
//  - duplicate faces (the same three vertices, in any order: both are dropped when they face
//    opposite ways, the second when they face the same way),
//  - faces at non-manifold edges (edges shared by more than two faces: all of that edge's
//    faces go; a graph-cut surface has few, where two inside regions touch along an edge),
//  - small connected components (fewer faces than `min_component_fraction` of the largest
//    component's): the floating pieces left by noise or stray points,
// and then the vertices no face uses. Non-manifold vertices (two fans meeting at a point) are
// kept: every viewer and glTF accept them, and they do not harm texturing.
//
// SimplifyMesh reduces the face count with meshoptimizer's quadric-error edge collapse
// (meshopt_simplify, Garland-Heckbert): flat areas lose their vertices first, so detail stays
// where the surface bends, i.e. where the photos showed relief. Borders are locked, so the
// trimmed outline of the model keeps its shape.
#ifndef RECONDUIT_CORE_MESH_MESH_CLEANING_H_
#define RECONDUIT_CORE_MESH_MESH_CLEANING_H_

#include "core/scene/triangle_mesh.h"

#include <cstddef>

namespace reconduit {

struct CleaningOptions {
  // Components with fewer faces than this share of the largest one's are removed. [0, 1]
  double min_component_fraction = 0.01;
};

struct CleaningSummary {
  std::size_t degenerate_faces = 0, duplicate_faces = 0, non_manifold_faces = 0,
              small_component_faces = 0;
  std::size_t components = 0, removed_components = 0;
  std::size_t unused_vertices = 0;
};

// Works on untextured meshes (texcoords must be empty: cleaning happens before texturing).
// Throws CheckError for out-of-range vertex indices.
CleaningSummary CleanMesh(TriangleMesh* mesh, const CleaningOptions& options = CleaningOptions());

struct SimplificationSummary {
  std::size_t faces_before = 0, faces_after = 0;
  // meshoptimizer's resulting error, relative to the mesh's extent.
  double relative_error = 0.0;
};

// Reduces `mesh` to at most about `target_faces` faces (unchanged when it has fewer) and
// removes the vertices no longer used; colours follow their vertices. Untextured meshes only.
SimplificationSummary SimplifyMesh(TriangleMesh* mesh, std::size_t target_faces);

// Area-weighted vertex normals from the faces (unit; zero for vertices of no face).
void ComputeVertexNormals(TriangleMesh* mesh);

// Removes the vertices no face uses, keeping the order of the others. Returns how many.
std::size_t RemoveUnusedVertices(TriangleMesh* mesh);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MESH_MESH_CLEANING_H_
