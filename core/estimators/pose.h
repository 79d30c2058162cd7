// Robust absolute pose of a calibrated camera from 2-D/3-D correspondences: LO-RANSAC with
// P3P samples (AP3P) and SQPnP + Levenberg-Marquardt local optimisation (solvers/absolute_pose.h).
#ifndef RECONDUIT_CORE_ESTIMATORS_POSE_H_
#define RECONDUIT_CORE_ESTIMATORS_POSE_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/optim/ransac_options.h"
#include "core/util/cancel.h"

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace reconduit {

struct AbsolutePoseOptions {
  // RANSAC settings; max_error is the reprojection error threshold in PIXELS (converted to
  // normalised units with the camera's focal length). 8 px is loose enough for 2-D points
  // matched against triangulated points that are themselves still noisy.
  RANSACOptions ransac = [] {
    RANSACOptions options;
    options.max_error = 8.0;
    return options;
  }();
  // Fewer inliers than this is a failure. >= 6 (the local estimator's minimum).
  int min_num_inliers = 10;

  bool Check(std::string* error) const;
};

struct AbsolutePoseReport {
  bool success = false;
  bool canceled = false;
  std::string message = "not run";
  Rigid3d cam_from_world;
  std::vector<char> inlier_mask;  // One entry per correspondence.
  std::size_t num_inliers = 0;
  std::size_t num_trials = 0;
};

// Estimates cam_from_world.
//
// @param camera             Intrinsics (focal, principal point, k1, k2) of the image.
// @param points2D           Observations in pixels of that image.
// @param points3D_in_world  Corresponding 3-D points; same size as points2D (else CheckError).
// @param options            Must pass Check() (else CheckError).
// @param cancel             Optional; caller keeps ownership.
// @return success = false with a message for fewer than 3 correspondences (or fewer than
//         min_num_inliers), degenerate data, or cancellation. Points whose pixel cannot be
//         undistorted are outliers.
AbsolutePoseReport EstimateAbsolutePose(const Camera& camera,
                                        const std::vector<Eigen::Vector2d>& points2D,
                                        const std::vector<Eigen::Vector3d>& points3D_in_world,
                                        const AbsolutePoseOptions& options,
                                        const CancelToken* cancel = nullptr);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_POSE_H_
