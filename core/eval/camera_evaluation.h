// Accuracy of recovered cameras against ground truth.
//
// A reconstruction from uncalibrated photos is defined up to a similarity, so the recovered
// camera centres are first aligned to the true ones with a 7-DoF least-squares similarity
// (Umeyama 1991, "Least-squares estimation of transformation parameters between two point
// patterns"). Then, per registered photo: the centre error (ground-truth units), the absolute
// rotation error after alignment, and over all pairs the relative-rotation error (which needs
// no alignment). The focal error compares our single focal with the ground truth's mean of
// fx and fy; where the ground truth's fx and fy differ (fountain-P11 by 0.17 %, templeSparseRing
// by 0.36 %) the errors against each are reported too, since a square-pixel model can only be
// as close to their mean as the photos let it be to both.
#ifndef RECONDUIT_CORE_EVAL_CAMERA_EVALUATION_H_
#define RECONDUIT_CORE_EVAL_CAMERA_EVALUATION_H_

#include "core/eval/ground_truth.h"
#include "core/scene/reconstruction.h"

#include <string>
#include <vector>

namespace reconduit {

struct CameraEvaluation {
  int num_ground_truth = 0;
  int num_registered = 0;          // Ground-truth photos present in the reconstruction.
  double mean_center_error = 0.0;  // Ground-truth units (metres for both datasets).
  double max_center_error = 0.0;
  // Mean centre error relative to the scene's radius: the mean distance of the true centres
  // from their centroid (the ring radius for a ring of photos), in percent.
  double mean_center_error_percent_of_radius = 0.0;
  double mean_rotation_error_deg = 0.0;           // After alignment.
  double mean_relative_rotation_error_deg = 0.0;  // Over all registered pairs.
  double max_relative_rotation_error_deg = 0.0;
  double mean_focal_error_percent = 0.0;  // |f - (fx+fy)/2| / ((fx+fy)/2).
  double max_focal_error_percent = 0.0;
  double mean_focal_error_x_percent = 0.0;  // |f - fx| / fx.
  double mean_focal_error_y_percent = 0.0;  // |f - fy| / fy.
  bool ground_truth_non_square = false;     // Some ground-truth fx != fy.
  std::vector<std::string> missing;         // Ground-truth photos not registered.

  std::string Report() const;
};

// Matches photos by name (RegisteredImage::name == GroundTruthCamera::name). At least three
// registered photos are needed for the alignment; with fewer, only counts are filled.
CameraEvaluation EvaluateCameras(const Reconstruction& reconstruction,
                                 const std::vector<GroundTruthCamera>& ground_truth);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_EVAL_CAMERA_EVALUATION_H_
