// Fundamental-matrix solvers: the 7-point (minimal) and normalised 8-point (non-minimal)
// algorithms, and the Sampson error.
//
// Convention: points1[i] and points2[i] are the same scene point seen in image 1 and image 2,
// in pixels (any consistent units work: the solvers normalise internally, Hartley 1997), and
// F maps image 1 to image 2:  [x2; 1]^T F [x1; 1] = 0.  F is returned with unit Frobenius
// norm; it is defined up to scale and sign.
#ifndef RECONDUIT_CORE_ESTIMATORS_SOLVERS_FUNDAMENTAL_MATRIX_H_
#define RECONDUIT_CORE_ESTIMATORS_SOLVERS_FUNDAMENTAL_MATRIX_H_

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// Minimal solver from 7 correspondences (Hartley & Zisserman 2nd ed., §11.1.2; Zhang 1998,
// "Determining the Epipolar Geometry and its Uncertainty: A Review", IJCV 27(2)). The 2-D null
// space of the 7x9 epipolar system gives the pencil a*F1 + (1-a)*F2; det = 0 is a cubic in a
// with 1 or 3 real roots, so up to 3 models are returned. No model when the sample is
// degenerate (coincident points, or a null space of dimension > 2, e.g. noise-free points on
// one plane).
class FundamentalMatrixSevenPointEstimator {
 public:
  using X_t = Eigen::Vector2d;  // Point in image 1 (pixels).
  using Y_t = Eigen::Vector2d;  // Point in image 2 (pixels).
  using M_t = Eigen::Matrix3d;  // F, with x2^T F x1 = 0.
  static constexpr int kMinNumSamples = 7;

  // @param points1, points2  Exactly 7 correspondences (else CheckError).
  // @param models            Output: 0 to 3 fundamental matrices (cleared first).
  static void Estimate(const std::vector<X_t>& points1,
                       const std::vector<Y_t>& points2,
                       std::vector<M_t>* models);

  // Squared Sampson error of each correspondence, in squared input units (pixels²).
  static void Residuals(const std::vector<X_t>& points1,
                        const std::vector<Y_t>& points2,
                        const M_t& F,
                        std::vector<double>* residuals);
};

// Normalised 8-point algorithm (Hartley 1997, "In Defense of the Eight-Point Algorithm", PAMI
// 19(6); Hartley & Zisserman alg. 11.1): linear least squares on >= 8 correspondences, then the
// closest rank-2 matrix. Used as LO-RANSAC's local estimator on all inliers of a 7-point model.
class FundamentalMatrixEightPointEstimator {
 public:
  using X_t = Eigen::Vector2d;
  using Y_t = Eigen::Vector2d;
  using M_t = Eigen::Matrix3d;
  static constexpr int kMinNumSamples = 8;

  // @param points1, points2  At least 8 correspondences of equal count (else CheckError).
  // @param models            Output: one model, or none when the system is degenerate.
  static void Estimate(const std::vector<X_t>& points1,
                       const std::vector<Y_t>& points2,
                       std::vector<M_t>* models);

  // Squared Sampson error, as FundamentalMatrixSevenPointEstimator::Residuals.
  static void Residuals(const std::vector<X_t>& points1,
                        const std::vector<Y_t>& points2,
                        const M_t& F,
                        std::vector<double>* residuals);

  // Polishes F on (at least 8) inliers by iteratively reweighted least squares: each row of
  // the 8-point system is divided by the gradient norm of its epipolar constraint, so that
  // the weighted algebraic error equals the Sampson error (the gradient-weighted scheme of
  // Zhang 1998, §5.2), and down-weighted by Tukey's biweight on its Sampson distance (scale
  // 4.685 * 1.4826 * median), so that the few mismatches that fall inside the RANSAC inlier
  // band do not pull the fit (plain algebraic least squares is sensitive to them). Rank 2 is
  // restored after each step. Leaves F unchanged when the system degenerates. LO-RANSAC calls it.
  static void Refine(const std::vector<X_t>& points1, const std::vector<Y_t>& points2, M_t* F);
};

// Squared Sampson error (Hartley & Zisserman §11.4.3), the first-order approximation of the
// squared distance of (x1, x2) in R^4 to the variety x2^T F x1 = 0:
//   (x2^T F x1)^2 / ((F x1)_0^2 + (F x1)_1^2 + (F^T x2)_0^2 + (F^T x2)_1^2).
// Works for F (pixels) and for an essential matrix E (normalised coordinates). Correspondences
// where the denominator vanishes (both points at the epipoles) get the largest double.
void ComputeSquaredSampsonError(const std::vector<Eigen::Vector2d>& points1,
                                const std::vector<Eigen::Vector2d>& points2,
                                const Eigen::Matrix3d& F,
                                std::vector<double>* residuals);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_SOLVERS_FUNDAMENTAL_MATRIX_H_
