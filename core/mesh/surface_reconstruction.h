// Surface reconstruction from the fused dense cloud: Delaunay tetrahedra labelled inside or
// outside by a visibility graph cut (Labatut, Pons and Keriven, "Efficient multi-view
// reconstruction of large-scale scenes using interest points, Delaunay triangulation and graph
// cuts", ICCV 2007; the method of OpenMVS's ReconstructMesh and of CGAL-based MVS pipelines).
//
// Why this method and not screened Poisson or TSDF fusion: the dense cloud carries, for every
// point, the photos that saw it (dense.ply's visibility). The line of sight from each photo to
// each point crosses empty space, so the tetrahedra it crosses are outside, and the space just
// behind the point is inside. A minimum cut of that evidence gives a surface that follows the
// points where they are dense and invents nothing where no line of sight says anything: the
// back of a façade and the background stay open instead of being closed by an implicit
// function (Poisson closes every surface and must be trimmed afterwards by density, which
// leaves ragged borders; TSDF needs a voxel size chosen for the whole scene). The Delaunay
// tetrahedralisation (CGAL, robust predicates) adapts to the points' density by itself.
//
// Steps (SurfaceSummary has the counts and times of each):
//  1. Decimation: points closer than `point_spacing_px` pixels of their nearest photo (its
//     footprint there) are merged: one representative per cell of a multi-level grid whose
//     cell side follows the footprint (powers of two), the point seen by most photos, with
//     the union of the cell's visibility. Dense maps give about one point per pixel and per
//     photo; a mesh needs far fewer vertices, and the graph cut's cost grows with them.
//  2. Delaunay tetrahedralisation of the kept points (CGAL::Delaunay_triangulation_3).
//  3. Visibility: for each point and each photo that sees it (at most `max_rays_per_point`,
//     nearest first), the segment from the point to the photo's centre is walked through the
//     tetrahedra (CGAL's segment traverser); each facet it crosses gets a weight of 1 on the
//     graph edge pointing from the camera's side to the point's side; the cell where the walk
//     ends (the camera's cell, or an infinite cell when the camera is outside the convex
//     hull) is tied to the source (outside), the cell `sink_distance_px` footprints behind
//     the point to the sink (inside).
//  4. Minimum s-t cut (Boykov-Kolmogorov max-flow, libmaxflow): source side = outside. Finite
//     cells the evidence leaves free are inside, infinite ones outside (so that the convex
//     hull's facets bound the model where they are on the data).
//  5. The surface: the facets between an inside and an outside cell, oriented towards the
//     outside (towards the cameras). Before that, where inside cells meet along an edge only
//     (the edge would carry four faces), the smaller group of them is made outside, so that
//     every edge of the surface has at most two faces (MakeEdgesManifold).
//  6. Trimming: faces with an edge longer than `max_edge_px` footprints of their vertices
//     are dropped: they span depth discontinuities and the open space around the data (the
//     "walls" other pipelines invent between a statue and its background); so are faces that
//     no photo seeing their corners sees from the front (the far side of the hull, behind a
//     façade that was photographed from one side only).
// Cleaning and simplification follow in mesh_cleaning.h and simplification.h.
//
// Memory: about 1 KB per kept point (triangulation, weights, graph), so 1.5 M kept points take
// ~1.5 GB. Threads: the walks (the costly step) run on `num_threads`.
#ifndef RECONDUIT_CORE_MESH_SURFACE_RECONSTRUCTION_H_
#define RECONDUIT_CORE_MESH_SURFACE_RECONSTRUCTION_H_

#include "core/mvs/fusion.h"
#include "core/scene/triangle_mesh.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {

// A photo as the surface reconstruction sees it: where it was taken and its focal length in
// the pixels of the depth maps (the dense stage's working size), for the points' footprints.
struct SurfaceView {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double focal_px = 1.0;
};

struct SurfaceOptions {
  // Points closer than this many footprints merge (step 1). [0.5, 50]
  // fountain-P11 at 1600 px (3.84 M fused points): 2 keeps 2.4 M points and takes 115 s for
  // 4.9 M faces, 4 keeps 0.91 M and takes 61 s for 1.8 M faces, more than the 500 k the mesh is
  // simplified to by default.
  double point_spacing_px = 4.0;
  // Lines of sight per point, the nearest photos first. [1, 64]
  int max_rays_per_point = 6;
  // How far behind a point its line of sight marks the space as inside, in footprints of the
  // point: the tetrahedron just behind it (Labatut et al.); farther, the cut may run anywhere
  // between the point and that tetrahedron, through space no evidence constrains. [0.1, 1000]
  double sink_distance_px = 1.0;
  // Faces with an edge longer than this many footprints of their longest-footprint vertex are
  // dropped (step 6). [2, 10000]
  double max_edge_px = 24.0;
  // Threads for the walks; the evidence does not depend on it (the cut only up to ties).
  int num_threads = 0;

  // False, with a message naming the field, for values out of range.
  bool Check(std::string* error) const;
};

struct SurfaceSummary {
  std::size_t input_points = 0;
  std::size_t kept_points = 0;  // After decimation (and merging of equal positions).
  std::size_t cells = 0;        // Tetrahedra, infinite ones included.
  std::size_t rays = 0;
  std::uint64_t facets_crossed = 0;  // By all walks: the cost of step 3.
  std::size_t inside_cells = 0;      // By the cut.
  std::size_t relabelled_cells = 0;  // Made outside for manifold edges (step 5).
  std::size_t cut_faces = 0;         // Step 5.
  std::size_t trimmed_faces = 0;     // Dropped in step 6 for their long edges.
  std::size_t unseen_faces = 0;      // Dropped in step 6: no photo saw their front.
  double seconds_decimation = 0.0, seconds_delaunay = 0.0, seconds_visibility = 0.0,
         seconds_cut = 0.0, seconds_extraction = 0.0;
};

struct SurfaceResult {
  // Positions and colours of the kept points that are vertices of a face (unused points are
  // removed); no normals yet (mesh_cleaning.h computes them after cleaning).
  TriangleMesh mesh;
  SurfaceSummary summary;
};

// `views[i]` is the photo that visibility id i in `cloud` refers to. Throws CheckError for
// invalid options, a visibility id without a view or a non-positive focal, and CanceledError
// when `cancel` fires. An empty cloud (or one too flat for a tetrahedron) gives an empty mesh.
SurfaceResult ReconstructSurface(const DenseCloud& cloud,
                                 const std::vector<SurfaceView>& views,
                                 const SurfaceOptions& options,
                                 Progress* progress = nullptr,
                                 const CancelToken& cancel = CancelToken());

// Per point, its footprint: the length one pixel covers at the point's distance from its
// nearest photo (distance / focal), the unit of the options above. 0 for points seen by none.
std::vector<float> PointFootprints(const DenseCloud& cloud, const std::vector<SurfaceView>& views);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MESH_SURFACE_RECONSTRUCTION_H_
