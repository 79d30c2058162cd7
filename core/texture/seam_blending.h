// Internal to core/texture: blending along chart borders, after the global levelling (issue 11:
// "seams levelled: a global colour adjustment per chart, and blending along chart borders").
//
// The per-chart offsets of LevelSeams remove what is constant over a chart (exposure, white
// balance); what is left at a border is local: shading that changed between the two photos,
// vignetting, a slightly different footprint. Along each border the two sides are pulled to a
// common colour, and the pull fades into each chart:
//  - every vertex where faces of two or more charts meet gets, per chart, the offset from that
//    chart's texel at the vertex to the mean over the charts there;
//  - the offsets spread into the chart over `band_rings` rings of its vertices (each ring the
//    mean of the previous ring's neighbours), scaled by 1 - d / (band_rings + 1) at ring d;
//  - each face of the chart adds the offsets of its corners, interpolated over the face, to its
//    texels (a mask keeps texels on edges shared by two faces from getting it twice).
// Waechter et al. blend with Poisson editing of a 20-pixel strip; this is the same idea with a
// piecewise-linear pull over whole faces: linear in the number of faces near a border, no
// system to solve, and exact at the vertices (both sides of a border show the same colour
// there). Faces of the mesh are a few texels wide at full resolution, so 2 rings are a band of
// about 5-15 texels.
// Measured on fountain-P11 (500 k faces, 38 k charts): 104 k border vertices differed from the
// mean of their charts by 3.0 grey levels after levelling (0 after blending); 407 k faces
// blended in 3.4 s on a loaded machine. The model rendered through each photo's camera moves
// little: in sample the first photo 8.71 -> 8.88 (its own charts are pulled towards their
// neighbours' colours), held out (0003, 0007 not used for the texture) 5.20 -> 5.29 and
// 7.95 -> 7.94: the blending removes the visible step at the borders, not a colour error.
#ifndef RECONDUIT_CORE_TEXTURE_SEAM_BLENDING_H_
#define RECONDUIT_CORE_TEXTURE_SEAM_BLENDING_H_

#include "core/scene/triangle_mesh.h"

#include <vector>

namespace reconduit::texture_internal {

struct SeamBlendSummary {
  int border_vertices = 0;  // Vertices where two or more charts meet.
  // Mean absolute difference (grey levels, over channels) between a border vertex's texel in a
  // chart and the mean over its charts, before blending (0 after it, at the vertices).
  double vertex_difference = 0.0;
  int blended_faces = 0;  // Faces whose texels changed.
};

// Blends `mesh`'s texture pages (CV_8UC3, texcoords and face_pages set) along the borders of
// the charts `face_chart` gives (per face, its chart, or -1 for faces outside every chart,
// which take no part). `band_rings` >= 0.
SeamBlendSummary BlendSeams(const std::vector<int>& face_chart, int band_rings, TriangleMesh* mesh);

}  // namespace reconduit::texture_internal

#endif  // RECONDUIT_CORE_TEXTURE_SEAM_BLENDING_H_
