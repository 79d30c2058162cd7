// Bundle adjustment: joint non-linear least-squares refinement of camera poses, intrinsics and
// 3-D points by minimising the reprojection error in pixels.
//
// The cost is  sum over observations of  rho(|| pi(K_c, cam_from_world_i * X_j) - x_ij ||^2
// / s_ij^2), where pi is exactly Camera::ImgFromCam (core/geometry/camera.h: pinhole with one
// focal length, principal point and radial k1, k2 on normalised coordinates; pixel centres at
// integers), x_ij is the keypoint in ORIGINAL-image pixels, s_ij its positional standard
// deviation in pixels (RegisteredImage::keypoint_stddevs, 1 when not given) and rho a robust
// loss (trivial, Huber or Cauchy) whose scale is in units of s_ij (pixels when s_ij = 1).
// The reported RMS errors are plain pixels. The problem is solved with Levenberg-Marquardt
// and the Schur complement trick, which eliminates the points first (Triggs, McLauchlan,
// Hartley & Fitzgibbon 2000, "Bundle adjustment -- a modern synthesis", §6.1); the solver is
// Ceres, kept behind this interface (bundle_adjustment_ceres.cc is the only implementation).
//
// Parameterisation: each pose is a unit quaternion (updated on the rotation manifold, no
// singularities) and a translation; each camera id has one intrinsics block [f, cx, cy, k1,
// k2] shared by all images of that camera; entries not refined are held constant.
//
// Gauge freedom (Triggs et al. §9): the reprojection error is unchanged by any similarity
// transform of the world (7 degrees of freedom: rotation, translation, scale). Bundle
// adjustment does not choose a gauge for you; the CALLER fixes it:
//   - With no constant pose the solution is free to drift (rotate, translate, scale) along
//     the null space of the problem; the normal equations are rank deficient and LM's damping
//     alone keeps the steps bounded. Only do this when the drift does not matter.
//   - One constant pose (constant_pose_image_ids) fixes rotation and translation (6 DoF).
//   - Scale is fixed additionally by holding one translation coordinate of a second image
//     constant (scale_fixing_image_id), as COLMAP does for its initial pair; or by a second
//     constant pose (which also removes that image's other 5 DoF from the refinement).
// In local bundle adjustment the images outside the variable set that see the adjusted points
// are held constant, which fixes the gauge whenever there are at least two of them.
//
// Thread-safety: BundleAdjust and RefinePose may run concurrently on DIFFERENT
// reconstructions; a Reconstruction is not thread-safe. Ceres uses `num_threads` threads
// internally to evaluate the Jacobian and solve the linear systems.
#ifndef RECONDUIT_CORE_SFM_BUNDLE_ADJUSTMENT_H_
#define RECONDUIT_CORE_SFM_BUNDLE_ADJUSTMENT_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/reconstruction.h"
#include "core/util/cancel.h"

#include <Eigen/Core>

#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

// The robust loss rho applied to the squared reprojection error of each observation.
enum class BundleAdjustmentLoss {
  kTrivial,  // rho(s) = s: plain least squares; optimal for Gaussian noise, ruined by outliers.
  kHuber,    // Quadratic up to `loss_scale` pixels, linear beyond: outliers get bounded weight.
  kCauchy,   // rho(s) = a² log(1 + s / a²): outliers' influence decays to zero; stronger than
             // Huber against gross mismatches, but less convex (needs a fair starting point).
};
std::string_view BundleAdjustmentLossName(BundleAdjustmentLoss loss);

// How the normal equations are solved (the reduced camera system after Schur elimination).
enum class BundleAdjustmentLinearSolver {
  kAuto,            // By the number of images with a variable pose, see the thresholds below.
  kDenseSchur,      // Dense Cholesky of the reduced camera matrix: fastest for few images.
  kSparseSchur,     // Sparse Cholesky (SuiteSparse CHOLMOD when available, else Eigen).
  kIterativeSchur,  // Preconditioned conjugate gradients (Schur-Jacobi): memory grows linearly.
};
std::string_view BundleAdjustmentLinearSolverName(BundleAdjustmentLinearSolver solver);

struct BundleAdjustmentOptions {
  // --- Cost ---------------------------------------------------------------------------------
  BundleAdjustmentLoss loss = BundleAdjustmentLoss::kTrivial;
  // Scale a of the robust loss in pixels, > 0: residuals below ~a count as inliers. Ignored
  // for kTrivial. 1 px matches the noise of SIFT keypoints at full resolution.
  double loss_scale = 1.0;

  // --- Intrinsics to refine (for every camera in the problem) -------------------------------
  // The focal length: yes by default, the whole point of self-calibration.
  bool refine_focal = true;
  // The principal point: no by default; it is poorly constrained (it trades off against the
  // rotation) and the image centre is accurate for almost every camera.
  bool refine_principal_point = false;
  // With refine_principal_point, one of its coordinates may still be held where it is (the
  // mapper's principal-point decision refines only the coordinates the photos determine).
  bool hold_principal_point_x = false;
  bool hold_principal_point_y = false;
  // Radial distortion. Set refine_k2 = false for k1 only (weak geometry, few points near the
  // image border), both false to keep the distortion as given.
  bool refine_k1 = true;
  bool refine_k2 = true;
  // Cameras whose intrinsics stay constant whatever the refine_* flags say (e.g. calibrated).
  std::vector<int> constant_camera_ids;

  // --- Poses and gauge ---------------------------------------------------------------------
  // Images whose pose (rotation and translation) stays constant. See the gauge note above.
  std::vector<int> constant_pose_image_ids;
  // When set (not kInvalidId), the image whose translation coordinate
  // `scale_fixing_translation_index` stays constant, fixing the scale of the reconstruction
  // (with one constant pose elsewhere). Must not also be in constant_pose_image_ids.
  int scale_fixing_image_id = kInvalidId;
  // 0, 1 or 2: which coordinate of cam_from_world.translation is held; -1 picks it
  // automatically: the largest coordinate of the direction, in that image's camera frame,
  // towards the first constant pose's centre (a coordinate near zero would not fix scale).
  int scale_fixing_translation_index = -1;

  // LOCAL bundle adjustment when not empty: only these images' poses vary; the points they
  // observe are adjusted with all their observations, and the other images that see those
  // points enter the problem with constant poses. Empty: GLOBAL adjustment of every image
  // and point of the reconstruction.
  std::vector<int> variable_pose_image_ids;

  // --- Solver -------------------------------------------------------------------------------
  // Levenberg-Marquardt iterations, > 0. BA from a good start converges in 10-50.
  int max_num_iterations = 100;
  // Stop when the relative cost decrease of an iteration is below this, > 0 (Ceres default
  // 1e-6; bundle adjustment wants a tighter one to reach COLMAP-grade accuracy).
  double function_tolerance = 1e-8;
  // Stop when the max-norm of the projected gradient is below this (relative), >= 0.
  double gradient_tolerance = 1e-12;
  // Stop when the relative step size is below this, >= 0.
  double parameter_tolerance = 1e-10;
  // Wall-time budget for the solve in seconds, > 0; the best solution so far is kept.
  double max_solver_time_seconds = 1e9;
  // Threads for Jacobian evaluation and linear algebra; <= 0 means all hardware threads (see
  // EffectiveNumThreads in core/util/parallel.h).
  int num_threads = -1;
  BundleAdjustmentLinearSolver linear_solver = BundleAdjustmentLinearSolver::kAuto;
  // kAuto thresholds on the number of variable-pose images, >= 1 and dense <= sparse: dense
  // Schur up to the first (the reduced camera matrix is at most 50·6 = 300 unknowns), sparse
  // Schur up to the second, iterative Schur beyond (a direct factorisation of a reduced camera
  // system with thousands of cameras and dense covisibility costs too much memory).
  int max_images_dense_schur = 50;
  int max_images_sparse_schur = 400;

  // --- Precision ------------------------------------------------------------------------------
  // After a usable solve, estimate each refined camera's intrinsics standard deviations from
  // the inverse of J^T J at the solution (ceres::Covariance, sparse QR), scaled by the a
  // posteriori variance factor (BundleAdjustmentSummary::variance_factor). Requires a fixed
  // gauge (a constant pose and a scale-fixing image); otherwise J^T J is singular and no
  // estimate is returned. First order, so read it as a lower bound where the focal is
  // weakly determined: in a synthetic Monte Carlo (12 photos, 200 points, focal known to
  // ~1 %) the focal's scatter was 1.16x the prediction at 0.05 px noise and 1.44x at
  // 0.5 px; the principal point's matched. Needs the trivial loss (Check()). Skipped when
  // cancellation was requested.
  bool estimate_intrinsics_stddev = false;
  // The sparse QR of the whole Jacobian (ceres::Covariance) grows faster than the problem:
  // about a second for fountain-P11's 56,000 observations here, 12 s for 50 synthetic aerial
  // photos. Above this many observations the points are eliminated from JᵀJ instead (Schur
  // complement, as the solver itself does) and the dense system left over the poses and
  // intrinsics is inverted by Cholesky: the same estimate to rounding (unit test), >= 0.
  int max_observations_for_stddev = 400000;
  // That dense system holds (6 n + 5 c)² doubles for n variable poses and c cameras (500
  // poses: 72 MB, a few seconds). Above this many variable poses no estimate is made (the
  // summary says so by an empty intrinsics_stddev), >= 0.
  int max_poses_for_stddev = 500;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

// One standard deviation of each intrinsic parameter (first-order, from J^T J at the
// solution): pixels for focal, cx, cy; unitless for k1, k2. Zero for an entry held constant.
struct IntrinsicsStddev {
  double focal = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double k1 = 0.0;
  double k2 = 0.0;
};

// What a solve did. The defaults read "not run": a summary nobody filled in is a failure.
struct BundleAdjustmentSummary {
  // True when the solver ran and its solution was written back (convergence, or the
  // iteration/time limit was reached with an improved or unchanged solution).
  bool success = false;
  std::string message = "bundle adjustment was not run";
  // Why the solver stopped: "CONVERGENCE", "NO_CONVERGENCE" (iteration or time limit),
  // "FAILURE", "USER_FAILURE" (canceled), or "NOT_RUN".
  std::string termination = "NOT_RUN";
  // The linear solver that was used, e.g. "DENSE_SCHUR".
  std::string linear_solver;

  // Problem size. Images and points that entered the problem, observations = residual blocks.
  int num_images = 0;
  int num_variable_images = 0;
  int num_cameras = 0;
  int num_points = 0;
  int num_observations = 0;
  // Points skipped because fewer than 2 of their observations are usable (in front of the
  // camera, in an image of the problem); observations skipped because the point was behind
  // the camera at the start.
  int num_skipped_points = 0;
  int num_skipped_observations = 0;

  // Robustified cost 1/2 sum rho(r²), as Ceres defines it, in pixels².
  double initial_cost = -1.0;
  double final_cost = -1.0;
  // Root-mean-square reprojection error over the observations in the problem, pixels (not
  // robustified: outliers count fully).
  double initial_rms_px = -1.0;
  double final_rms_px = -1.0;
  int num_iterations = 0;
  double time_seconds = 0.0;

  // With BundleAdjustmentOptions::estimate_intrinsics_stddev: per camera id whose intrinsics
  // were refined, their standard deviations; empty when not asked for or not estimable
  // (gauge not fixed, rank-deficient problem). variance_factor is the a posteriori variance
  // of a unit-weight residual, 2 x final_cost / (residuals - parameters): near 1 when the
  // keypoint standard deviations are right; the covariance is scaled by it, so the estimate
  // does not rely on them being exact.
  std::map<int, IntrinsicsStddev> intrinsics_stddev;
  double variance_factor = 0.0;

  // One line: "BA CONVERGENCE: 12 images (10 variable), 3000 points, 15000 obs, rms 1.2 ->
  // 0.45 px, 8 iterations, 0.31 s (DENSE_SCHUR)".
  std::string BriefReport() const;
};

// Refines the reconstruction in place by bundle adjustment.
//
// Reads and writes cameras (intrinsics), images[...].cam_from_world and
// points[...].xyz_in_world; only parameters that are variable in the problem change (constant
// ones are bit-identical afterwards); observations and the point set are not modified.
// Quaternions stay normalised.
//
// Cancellation: `cancel` is polled before the solve and at every solver iteration (a Ceres
// IterationCallback). When it fires, the solver aborts, nothing is written back (the
// reconstruction is exactly as it was before the call, hence consistent), and CanceledError
// is thrown.
//
// @param options   Must pass Check(); throws CheckError otherwise (a precondition).
// @param cancel    Cancellation token; not stored beyond the call.
// @param reconstruction  Not owned; must be non-null. Image, camera and point ids named in the
//                  options must exist in it (CheckError otherwise); every image's camera and
//                  every observation's keypoint must exist.
// @return          The summary; success=false with a message when there is nothing to adjust
//                  (e.g. an empty reconstruction) or the solver failed.
BundleAdjustmentSummary BundleAdjust(const BundleAdjustmentOptions& options,
                                     const CancelToken& cancel,
                                     Reconstruction* reconstruction);

// Options of motion-only refinement (RefinePose).
struct PoseRefinementOptions {
  // Robust by default: pose refinement follows PnP-RANSAC, whose inlier threshold lets some
  // mismatches through.
  BundleAdjustmentLoss loss = BundleAdjustmentLoss::kCauchy;
  // Robust loss scale in pixels, > 0.
  double loss_scale = 1.0;
  // > 0. A pose from PnP needs a handful of iterations.
  int max_num_iterations = 100;
  // As in BundleAdjustmentOptions, > 0, >= 0, >= 0.
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;

  bool Check(std::string* error) const;
};

// Motion-only bundle adjustment: refines one camera's pose against fixed 3-D points and fixed
// intrinsics by minimising the robustified reprojection error (used after PnP registration).
//
// @param options   Must pass Check() (CheckError otherwise).
// @param camera    Intrinsics, held constant; pixels in the image the camera describes.
// @param points2D  Observed keypoints, pixels; same length as points3D.
// @param points3D  World points, held constant.
// @param cam_from_world  In: the initial pose; out: the refined pose (only written on
//                  success). Not owned; must be non-null.
// @return          The summary (num_points = num_observations = correspondences used).
//                  success=false when fewer than 3 correspondences are in front of the initial
//                  camera or the solver failed.
BundleAdjustmentSummary RefinePose(const PoseRefinementOptions& options,
                                   const Camera& camera,
                                   const std::vector<Eigen::Vector2d>& points2D,
                                   const std::vector<Eigen::Vector3d>& points3D,
                                   Rigid3d* cam_from_world);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_BUNDLE_ADJUSTMENT_H_
