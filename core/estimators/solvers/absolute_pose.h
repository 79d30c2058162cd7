// Absolute pose (PnP) solvers for calibrated cameras, wrapping OpenCV's calib3d.
//
// Why OpenCV here: cv::solveP3P (Ke & Roumeliotis 2017, "An Efficient Algebraic Solution to
// the Perspective-Three-Point Problem", CVPR; SOLVEPNP_AP3P) and cv::solvePnP with SQPnP
// (Terzakis & Lourakis 2020, "A Consistently Fast and Globally Optimal Solution to the
// Perspective-n-Point Problem", ECCV) plus cv::solvePnPRefineLM are mature, tested solvers that
// take exactly our data (3-D points and normalised image points with K = I). We keep the
// robust loop (our LO-RANSAC) rather than cv::solvePnPRansac for the same reasons as in
// two_view_geometry.h: a seed, cancellation, MSAC scoring and our Report.
//
// Units and frames: X_t are NORMALISED image coordinates (undistorted, K removed: the point
// (x/z, y/z) of the viewing ray in the camera frame); Y_t are 3-D points in the world frame;
// the model is cam_from_world as a 3x4 matrix [R | t] (x_cam = R x_world + t).
#ifndef RECONDUIT_CORE_ESTIMATORS_SOLVERS_ABSOLUTE_POSE_H_
#define RECONDUIT_CORE_ESTIMATORS_SOLVERS_ABSOLUTE_POSE_H_

#include "core/geometry/rigid3.h"

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// Minimal P3P: up to 4 poses from 3 correspondences (cv::solveP3P, SOLVEPNP_AP3P). No model
// for degenerate samples (collinear 3-D points, coincident rays).
class P3PEstimator {
 public:
  using X_t = Eigen::Vector2d;  // Normalised image point.
  using Y_t = Eigen::Vector3d;  // World point.
  using M_t = Matrix3x4d;       // cam_from_world [R | t].
  static constexpr int kMinNumSamples = 3;

  // @param points2D, points3D  Exactly 3 correspondences (else CheckError).
  static void Estimate(const std::vector<X_t>& points2D,
                       const std::vector<Y_t>& points3D,
                       std::vector<M_t>* models);

  // Squared reprojection error in normalised units (divide pixel thresholds by the focal
  // length). Points at or behind the camera get the largest double.
  static void Residuals(const std::vector<X_t>& points2D,
                        const std::vector<Y_t>& points3D,
                        const M_t& cam_from_world,
                        std::vector<double>* residuals);
};

// Non-minimal PnP for LO-RANSAC: SQPnP on >= 6 inliers (globally optimal for its algebraic
// cost), and Refine = Levenberg-Marquardt on the reprojection error (cv::solvePnPRefineLM).
class PnPNonMinimalEstimator {
 public:
  using X_t = Eigen::Vector2d;
  using Y_t = Eigen::Vector3d;
  using M_t = Matrix3x4d;
  static constexpr int kMinNumSamples = 6;

  static void Estimate(const std::vector<X_t>& points2D,
                       const std::vector<Y_t>& points3D,
                       std::vector<M_t>* models);
  static void Residuals(const std::vector<X_t>& points2D,
                        const std::vector<Y_t>& points3D,
                        const M_t& cam_from_world,
                        std::vector<double>* residuals);
  // Leaves the model unchanged when OpenCV fails or returns non-finite values.
  static void Refine(const std::vector<X_t>& points2D,
                     const std::vector<Y_t>& points3D,
                     M_t* cam_from_world);
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_SOLVERS_ABSOLUTE_POSE_H_
