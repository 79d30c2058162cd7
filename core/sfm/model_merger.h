// Merging two reconstructions of the same scene (issue 13): models that share registered
// photos (same image ids) or points (observations of the same track) are brought into one
// frame by a 7-DoF similarity and joined.
//
//  1. Correspondences: every photo registered in both models gives its camera centre (and its
//     orientation); every point of B linked to a point of A gives its position. Points are
//     linked by a shared observation (same photo and keypoint), or, when the caller passes the
//     track of every keypoint, by a shared track (then models without a common photo can be
//     linked too).
//  2. Similarity A <- B, robustly: RANSAC over hypotheses from three positions (Umeyama 1991,
//     Eigen::umeyama) and from two shared photos (the rotation from one photo's orientation in
//     both models, scale and translation from the two centres: this still works when the
//     shared centres are collinear and no point is shared). A correspondence agrees when its
//     position lands within `max_alignment_error` x its distance scale (the model's extent, or
//     the point's distance from the cameras when larger) and, for a photo, its orientation
//     within `max_rotation_error_deg`. The best hypothesis is refitted on its inliers (Umeyama
//     when they span a plane). The merge is refused with too few agreeing correspondences or
//     too small a share of them.
//  3. Union: A's photos and points stay; B's photos that A lacks are added with their poses
//     mapped into A's frame; B's points linked to an agreeing A point are fused into it (their
//     observations added where the keypoint is free), the others are added mapped.
//  4. A joint bundle adjustment (robust loss), then observations reprojecting worse than
//     `max_reprojection_error_px` are removed. The merge is refused when the merged model's
//     mean reprojection error exceeds `max_error_growth` x the larger of the two inputs'.
#ifndef RECONDUIT_CORE_SFM_MODEL_MERGER_H_
#define RECONDUIT_CORE_SFM_MODEL_MERGER_H_

#include "core/scene/reconstruction.h"
#include "core/sfm/bundle_adjustment.h"
#include "core/util/cancel.h"

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace reconduit {

// x_a = scale * rotation * x_b + translation.
struct Similarity3 {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x_b) const {
    return scale * (rotation * x_b) + translation;
  }
  // The cam_from_world pose, in A's frame, of a camera whose pose in B's frame is `b_pose`.
  Rigid3d MapPose(const Rigid3d& b_pose) const;
};

struct ModelMergerOptions {
  // A correspondence agrees with a similarity when its mapped position is within this share
  // of its distance scale (see the file comment). (0, 1)
  double max_alignment_error = 0.02;
  // A shared photo also needs its orientations to agree within this angle, degrees. (0, 180)
  double max_rotation_error_deg = 3.0;
  // At least this many agreeing correspondences (photos and points) ... [3, ...]
  int min_inliers = 6;
  // ... and this share of all of them. (0, 1]
  double min_inlier_ratio = 0.5;
  // RANSAC hypotheses from random triples of positions. [1, ...]
  int ransac_iterations = 300;
  std::uint64_t seed = 0x13b;
  // After the joint adjustment, observations worse than this are removed, pixels. (0, ...)
  double max_reprojection_error_px = 4.0;
  // Refusal after the joint adjustment: mean reprojection error above this factor x the larger
  // of the two models' (and above `max_reprojection_error_px` / 2). [1, ...]
  double max_error_growth = 1.5;

  bool Check(std::string* error) const;
};

// The track of every keypoint, by image id (-1: none); see the file comment.
using KeypointTracks = std::map<int, std::vector<int>>;

struct ModelCorrespondences {
  std::vector<int> images;                  // Registered in both models.
  std::vector<std::pair<int, int>> points;  // (point id in A, point id in B), each once.
};

// The photos and points the two models share; `tracks` may be null (points linked by shared
// observations only).
ModelCorrespondences FindModelCorrespondences(const Reconstruction& a,
                                              const Reconstruction& b,
                                              const KeypointTracks* tracks);

struct ModelAlignment {
  Similarity3 a_from_b;
  int num_images = 0;  // Shared photos ...
  int num_points = 0;  // ... and points considered.
  int num_inlier_images = 0;
  int num_inlier_points = 0;
  std::vector<bool> point_inliers;  // Per ModelCorrespondences::points.
};

// The similarity A <- B from the correspondences (steps 1-2). nullopt with the reason in `why`
// when it is refused (too few or inconsistent correspondences, degenerate configuration).
std::optional<ModelAlignment> AlignModels(const Reconstruction& a,
                                          const Reconstruction& b,
                                          const ModelCorrespondences& correspondences,
                                          const ModelMergerOptions& options,
                                          std::string* why);

// Step 3: B joined into A (in A's frame) with `alignment`; A's poses of shared photos stay.
void JoinModels(const Reconstruction& b,
                const ModelCorrespondences& correspondences,
                const ModelAlignment& alignment,
                Reconstruction* a);

struct MergeSummary {
  bool merged = false;
  std::string message;  // The log line: merged or why not.
  int num_images_a = 0;
  int num_images_b = 0;
  int num_images = 0;  // Of the merged model.
  ModelAlignment alignment;
};

// Steps 1-4: merges B into A. `bundle` gives the joint adjustment's solver settings and, when
// it names none, the gauge is fixed by A's first two photos. A is left unchanged when the
// merge is refused.
MergeSummary MergeModels(const Reconstruction& b,
                         const KeypointTracks* tracks,
                         const ModelMergerOptions& options,
                         const BundleAdjustmentOptions& bundle,
                         const CancelToken& cancel,
                         Reconstruction* a);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_MODEL_MERGER_H_
