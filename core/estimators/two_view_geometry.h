// Two-view geometry of an uncalibrated image pair: robust F and H, and Torr's GRIC to choose.
//
// EstimateTwoViewGeometry fits a fundamental matrix (LO-RANSAC: 7-point samples, normalised
// 8-point local optimisation, MSAC scoring) and a homography (LO-RANSAC: 4-point DLT samples,
// DLT on all inliers) to putative matches, then compares them with GRIC (gric.h). A pair
// whose matches a homography explains as well as F (a planar scene, a pure rotation, or a
// baseline negligible against the depth) is labelled kHomography: its F is unreliable and
// it must not initialise a reconstruction (issue 3, "Structure and motion").
//
// Why our own RANSAC and not OpenCV's cv::findFundamentalMat(USAC_MAGSAC) /
// cv::findHomography: GRIC needs both models scored with the SAME residuals and inlier
// sets, OpenCV's USAC returns only a mask and uses its own (MAGSAC-weighted) thresholds; we
// also need a seed for reproducible runs (USAC has one, the classic methods do not),
// cancellation inside the loop, and the reports (trials, support) in our own types. The
// solvers are small and tested against ground truth; MAGSAC++ remains an option for the
// matcher if our LO-RANSAC proves weaker on real data.
//
// Units: all points, thresholds and sigma are in PIXELS of the images the points come from;
// F and H map image 1 to image 2 (x2^T F x1 = 0, x2 ~ H x1).
#ifndef RECONDUIT_CORE_ESTIMATORS_TWO_VIEW_GEOMETRY_H_
#define RECONDUIT_CORE_ESTIMATORS_TWO_VIEW_GEOMETRY_H_

#include "core/optim/ransac_options.h"
#include "core/util/cancel.h"

#include <Eigen/Core>

#include <cstddef>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

enum class TwoViewModelType {
  kUndefined,    // Default: not estimated.
  kDegenerate,   // Too few matches or inliers, or degenerate point sets: no usable geometry.
  kFundamental,  // General epipolar geometry with a real baseline: F is meaningful.
  kHomography,   // Planar scene or pure rotation (GRIC prefers H): do not initialise from it.
};

// "undefined", "degenerate", "fundamental", "homography".
std::string_view TwoViewModelTypeName(TwoViewModelType type);

struct TwoViewGeometryOptions {
  // RANSAC for F. max_error is the Sampson distance threshold in pixels: the first-order
  // distance in R^4 has one degree of freedom, so 3 px keeps 99.7 % of inliers at 1 px noise.
  // The same trial settings and seed are used for H.
  RANSACOptions ransac = [] {
    RANSACOptions options;
    options.max_error = 3.0;
    return options;
  }();

  // Inlier threshold for H in pixels, on sqrt(symmetric transfer error): that error adds the
  // forward and backward transfer errors and each carries noise from both images, so it is
  // about twice the Sampson distance; 6 px keeps ~99 % of inliers at 1 px noise. > 0
  double homography_max_error = 6.0;

  // A model needs at least this many inliers to count; with fewer for both, the pair is
  // kDegenerate. >= 7 (the 7-point sample size). 20, not COLMAP's 15: among ~30 putative
  // matches, RANSAC finds an F that 15 false ones fit within 3 px (templeSparseRing every
  // second photo: two pairs 147 and 157 deg apart, 15 inliers each, took the focal from 1.1 %
  // to 2.7 % off; tests/wide_gap_test), while the true pairs kept there have 33 or more; the
  // other sets (fountain, temple, kermit, few_features_test) keep their figures.
  int min_num_inliers = 20;

  // Image noise standard deviation in pixels for GRIC. <= 0 (default): estimated from the F
  // inliers as 1.4826 * median(Sampson distance) (the Sampson distance of an inlier is a 1-D
  // Gaussian residual); from the H inliers' Sampson errors (2 degrees of freedom) instead
  // when F failed or H has >= 90 % as many inliers as F (then F is nearly degenerate and
  // overfits the noise); never below 0.1 px.
  double gric_sigma = 0.0;

  // False, with a message naming the field, when a value is out of range.
  bool Check(std::string* error) const;
};

// What EstimateTwoViewGeometry found. A default report reads as failure.
struct TwoViewGeometryReport {
  // True when a usable model (F or H) was found; type then says which one to trust.
  bool success = false;
  bool canceled = false;
  // Why the pair failed; empty on success.
  std::string message = "not run";
  TwoViewModelType type = TwoViewModelType::kUndefined;

  // Fundamental matrix (unit Frobenius norm) and its inliers, valid when num_inliers_F > 0.
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  std::vector<char> inlier_mask_F;  // One entry per match: 1 = inlier of F.
  std::size_t num_inliers_F = 0;
  std::size_t num_trials_F = 0;

  // Homography (unit Frobenius norm) and its inliers, valid when num_inliers_H > 0.
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  std::vector<char> inlier_mask_H;
  std::size_t num_inliers_H = 0;
  std::size_t num_trials_H = 0;

  // GRIC scores (lower is better), over the matches that are inliers of F or of H; infinity
  // for a model that was not found.
  double gric_F = std::numeric_limits<double>::infinity();
  double gric_H = std::numeric_limits<double>::infinity();
  // Noise sigma used for GRIC, in pixels, and the number of matches scored.
  double gric_sigma = 0.0;
  std::size_t num_gric_matches = 0;

  // The inlier mask of the chosen model (F for kFundamental, H for kHomography, else empty).
  const std::vector<char>& inlier_mask() const;
};

// Robust two-view geometry of putative matches between two uncalibrated images.
//
// @param points1, points2  Matched keypoints in pixels, points1[i] <-> points2[i]; equal
//                          sizes (else CheckError).
// @param options           Must pass Check() (else CheckError).
// @param cancel            Optional, polled inside the RANSAC loops; caller keeps ownership.
// @return A report. success = false with type kDegenerate and a message for fewer than 7
//         matches, coincident or collinear points (within options.ransac.max_error), or when
//         neither model reaches min_num_inliers; it never throws for such data.
//
// Thread-safety: reentrant (no shared state).
TwoViewGeometryReport EstimateTwoViewGeometry(const std::vector<Eigen::Vector2d>& points1,
                                              const std::vector<Eigen::Vector2d>& points2,
                                              const TwoViewGeometryOptions& options,
                                              const CancelToken* cancel = nullptr);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_TWO_VIEW_GEOMETRY_H_
