// Homography solver (normalised DLT) and homography errors.
//
// Convention: H maps image 1 to image 2, [x2; 1] ~ H [x1; 1], points in pixels (any
// consistent units). A homography relates two views of a plane, or two views of any scene
// taken from the same centre (pure rotation, or a baseline negligible against the depth).
#ifndef RECONDUIT_CORE_ESTIMATORS_SOLVERS_HOMOGRAPHY_MATRIX_H_
#define RECONDUIT_CORE_ESTIMATORS_SOLVERS_HOMOGRAPHY_MATRIX_H_

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// Normalised direct linear transformation (Hartley & Zisserman 2nd ed., alg. 4.2) from >= 4
// correspondences; minimal with 4 (kMinNumSamples) and least squares with more, so it serves
// as both the minimal and the local estimator of LO-RANSAC. No model when the sample is
// degenerate (coincident points, three of four collinear, or a singular result).
class HomographyMatrixEstimator {
 public:
  using X_t = Eigen::Vector2d;  // Point in image 1 (pixels).
  using Y_t = Eigen::Vector2d;  // Point in image 2 (pixels).
  using M_t = Eigen::Matrix3d;  // H, with x2 ~ H x1; unit Frobenius norm.
  static constexpr int kMinNumSamples = 4;

  // @param points1, points2  At least 4 correspondences of equal count (else CheckError).
  // @param models            Output: one model or none (cleared first).
  static void Estimate(const std::vector<X_t>& points1,
                       const std::vector<Y_t>& points2,
                       std::vector<M_t>* models);

  // Squared symmetric transfer error (H&Z eq. 4.7), in squared input units (pixels²):
  //   |x2 - H x1|² + |x1 - H^-1 x2|²   (dehomogenised).
  // Points mapped to infinity, and every point when H is singular, get the largest double.
  static void Residuals(const std::vector<X_t>& points1,
                        const std::vector<Y_t>& points2,
                        const M_t& H,
                        std::vector<double>* residuals);
};

// Squared Sampson error of a homography (H&Z §4.2.6): the first-order approximation of the
// squared distance of (x1, x2) in R^4 to the 2-D variety x2 ~ H x1, i.e. of the reprojection
// (gold standard) error with noise in both images. Unlike the symmetric transfer error it is
// on the same scale as the Sampson error of F, which model selection (GRIC) needs. Pixels².
void ComputeHomographySquaredSampsonError(const std::vector<Eigen::Vector2d>& points1,
                                          const std::vector<Eigen::Vector2d>& points2,
                                          const Eigen::Matrix3d& H,
                                          std::vector<double>* residuals);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_SOLVERS_HOMOGRAPHY_MATRIX_H_
