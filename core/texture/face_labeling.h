// Steps 1-3 of TextureMesh (texture_mesh.h): which views see which faces, one view per face,
// and the charts of connected faces sharing a view. Exposed for tests and for tools that want
// the labelling without baking.
#ifndef RECONDUIT_CORE_TEXTURE_FACE_LABELING_H_
#define RECONDUIT_CORE_TEXTURE_FACE_LABELING_H_

#include "core/texture/texture_mesh.h"

#include <vector>

namespace reconduit {

struct FaceCandidate {
  int view = -1;
  // Projected area in full-resolution photo pixels times the cosine of the viewing angle, > 0.
  float quality = 0.0f;
};

// Per face, the views that may texture it, as compressed rows: the candidates of face f are
// items[offsets[f]] .. items[offsets[f + 1] - 1], by increasing view index.
struct FaceCandidates {
  std::vector<int> offsets;
  std::vector<FaceCandidate> items;
  int NumCandidates(int face) const { return offsets[face + 1] - offsets[face]; }
};

// Faces sharing an edge, as compressed rows (neighbours of f: neighbors[offsets[f]] ..
// neighbors[offsets[f + 1] - 1]). An edge of k > 2 faces (non-manifold) links all k.
struct FaceAdjacency {
  std::vector<int> offsets;
  std::vector<int> neighbors;
};

struct Charts {
  std::vector<int> face_chart;                // Per face, its chart, or -1 for unlabelled faces.
  std::vector<int> chart_view;                // Per chart, its view.
  std::vector<std::vector<int>> chart_faces;  // Per chart, its faces, increasing.
};

// Step 1, visibility. For each view (in parallel, options.num_threads) the mesh's depth is
// rendered into a z-buffer of the camera scaled to at most options.visibility_max_side (with
// its distortion: vertices are projected through it and triangles drawn straight between them,
// exact to far below a z-buffer pixel for faces of a few pixels). A face is a candidate for the
// view when its three corners project inside the photo, it faces the camera within
// options.max_view_angle_deg, and its centroid and three points halfway between the centroid
// and its corners are no farther than (1 + depth_tolerance) x the z-buffer's depth: a face
// partly hidden is no candidate, so an occluder's colour is never baked onto it.
// Quality (the data term's input) is the projected area at full resolution, which already
// falls with distance² and with the cosine of the angle, times that cosine once more: at equal
// resolution a frontal view is preferred because grazing views smear texture and suffer most
// from small pose and geometry errors (mvs-texturing's "area" data term weights the same way
// through the projected area; its gradient-magnitude term additionally favours sharp photos,
// which needs the photos at selection time and costs a pass over them).
FaceCandidates ComputeFaceCandidates(const TriangleMesh& mesh,
                                     const std::vector<TextureView>& views,
                                     const TextureOptions& options,
                                     Progress* progress,
                                     const CancelToken& cancel);

FaceAdjacency ComputeFaceAdjacency(const TriangleMesh& mesh);

// Per face, its candidate of highest quality (lowest view index on ties), or -1.
std::vector<int> SelectBestViews(const FaceCandidates& candidates);

// Step 2, smoothing, in place on `labels` (start: SelectBestViews). Energy:
//   E = sum_f D(f, l_f) + smoothness_weight * #{adjacent pairs (f, g), both labelled, l_f != l_g}
// with D(f, v) = 1 - quality(f, v) / max_v quality(f, v) in [0, 1): the data cost is relative
// to the face's best view, so the weight means the same for large and small faces and for near
// and far views. Minimised from the greedy start by two kinds of moves, each lowering E (so it
// converges), alternated until neither changes anything or max_sweeps sweeps are done:
//  - iterated conditional modes: each face in turn takes the candidate label minimising its
//    terms. It removes single-face islands and ragged borders, but on a triangle mesh an island
//    with straight borders is a local minimum (each border face has one differing neighbour);
//    measured in face_labeling_test on a jittered wall: 549 greedy charts -> 170 with ICM only;
//  - chart moves: a whole chart takes the label of a neighbouring chart when all its faces see
//    that view and E drops (the expansion move of graph cuts restricted to whole charts),
//    which removes those islands: 549 -> 3 charts (energy 867 -> 100) in 36 sweeps.
// Full alpha-expansion (Boykov-Veksler-Zabih, max-flow per label) would find better minima
// still (a chart could split along its best border), at ~labels x max-flow cost per sweep.
// Returns the sweeps done. Faces with label -1 keep it and do not count in the Potts term.
int SmoothLabels(const FaceCandidates& candidates,
                 const FaceAdjacency& adjacency,
                 double smoothness_weight,
                 int max_sweeps,
                 std::vector<int>* labels);

// Step 3: connected components of labelled faces with equal labels.
Charts ComputeCharts(const std::vector<int>& labels, const FaceAdjacency& adjacency);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_TEXTURE_FACE_LABELING_H_
