// View selection for dense matching: for each reference photo, the neighbours that see the same
// surface with a useful triangulation angle and a similar resolution.
//
// The score of a neighbour is a sum over the sparse points the two photos share, as in Goesele
// et al., "Multi-view stereo for community photo collections" (ICCV 2007), whose weights are
// used by COLMAP and OpenMVS alike:
//   score(ref, src) = sum over shared points p of  w_angle(theta_p) * w_scale(ratio_p)
// - theta_p is the angle at p between the rays to the two camera centres. Depth from a small
//   angle is poorly conditioned, so w_angle = min(theta / ideal, 1)^2, and 0 below `min` (too
//   little parallax to be worth matching) or above `max` (the two photos see the surface from
//   such different sides that patches no longer look alike).
// - ratio_p is the size of a pixel's footprint at p in the neighbour over that in the
//   reference (depth / focal in each). A coarser neighbour (ratio > 1) blurs the match,
//   w_scale = 1 / ratio; a neighbour up to twice as fine is as good as an equal one, and a much
//   finer one is penalised mildly, w_scale = 2 ratio below 0.5 (its pixels are averaged away).
// Points are what the sparse stage reconstructed, so the score also measures overlap: photos
// that share no points are never neighbours.
//
// Sources for coverage (`coverage_sources`): PatchMatch matches a reference only against its
// first few neighbours, and the best-scored ones tend to see the same part of the reference
// (wide baselines to the middle of the scene), while surface that only one other photo sees,
// often a nearby one with a small (lower-scored) angle, then gets no depth. So the first
// `coverage_sources` neighbours are chosen greedily: the best-scored first, then each time the
// neighbour with the largest gain over the reference's sparse points it shares, where a point
// no chosen neighbour sees yet counts 1 and one seen by c chosen neighbours counts its weight
// w_angle * w_scale times 2^-c (a second source still helps the top-2 cost, a sixth little).
// The rest follow by score. Measured on tests/dense_synthetic_test's long variant (box room,
// 8 photos on a line, 7 neighbours each, 6 sources): completeness over surface seen by >= 2
// photos 89.2 % (no noise) and 89.3 % (noise) by score alone, where each photo dropped its
// nearest neighbour (the smallest angle), often the only other photo that sees the room's
// corners; 94.6 % and 94.2 % with coverage (>= 3 photos: 97.3 -> 97.9 %, 97.5 -> 97.6 %).
// The number of sources, hence PatchMatch's time, does not change.
#ifndef RECONDUIT_CORE_MVS_VIEW_SELECTION_H_
#define RECONDUIT_CORE_MVS_VIEW_SELECTION_H_

#include "core/scene/reconstruction.h"

#include <map>
#include <string>
#include <vector>

namespace reconduit {

struct ViewSelectionOptions {
  // At most this many neighbours per reference photo. [1, 32]
  int max_neighbors = 8;
  // A neighbour must share at least this many points whose angle is in [min, max]. [1, 10000]
  int min_shared_points = 12;
  // Triangulation angles in degrees: below `min` and above `max` a point does not count, at or
  // above `ideal` it counts fully. 0 < min <= ideal <= max <= 90.
  double min_triangulation_angle_deg = 1.0;
  double ideal_triangulation_angle_deg = 10.0;
  double max_triangulation_angle_deg = 60.0;
  // Neighbours scoring below this share of the best neighbour's score are dropped. [0, 1]
  double min_relative_score = 0.05;
  // The first this many neighbours are chosen for coverage of the reference (see above);
  // 0: all by score. The dense stage sets it to its number of PatchMatch sources. [0, 32]
  int coverage_sources = 6;

  // False, with a message naming the field, when a value is out of range.
  bool Check(std::string* error) const;
};

struct ViewNeighbor {
  int image_id = -1;
  double score = 0.0;
  // Points shared with the reference whose angle is within [min, max].
  int shared_points = 0;
  // Median triangulation angle over those points, degrees.
  double median_angle_deg = 0.0;
  // Median footprint ratio (neighbour / reference) over those points.
  double median_scale_ratio = 0.0;
};

// The neighbours of every registered image of `model`, best first; an image with no
// acceptable neighbour maps to an empty list. Throws CheckError for invalid options.
// Deterministic; O(observations x neighbours).
std::map<int, std::vector<ViewNeighbor>> SelectViews(const Reconstruction& model,
                                                     const ViewSelectionOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_VIEW_SELECTION_H_
