#include "core/estimators/solvers/homography_matrix.h"

#include "core/estimators/normalization.h"
#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>

namespace reconduit {
namespace {

constexpr double kMaxResidual = std::numeric_limits<double>::max();
// A singular value below this fraction of the largest counts as zero.
constexpr double kRankTolerance = 1e-10;

}  // namespace

void HomographyMatrixEstimator::Estimate(const std::vector<X_t>& points1,
                                         const std::vector<Y_t>& points2,
                                         std::vector<M_t>* models) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_GE(points1.size(), 4);
  THROW_CHECK_NOTNULL(models);
  models->clear();

  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!CenterAndNormalizeImagePoints(points1, &n1, &T1) ||
      !CenterAndNormalizeImagePoints(points2, &n2, &T2)) {
    return;
  }

  // Two rows of x2 x (H x1) = 0 per correspondence (H&Z eq. 4.3), h row-major.
  const Eigen::Index num_points = static_cast<Eigen::Index>(points1.size());
  const auto fill_rows = [&](auto* A) {
    for (Eigen::Index i = 0; i < num_points; ++i) {
      const Eigen::Vector3d x1 = n1[i].homogeneous();
      const double u2 = n2[i].x(), v2 = n2[i].y();
      A->row(2 * i) << 0.0, 0.0, 0.0, -x1.transpose(), v2 * x1.transpose();
      A->row(2 * i + 1) << x1.transpose(), 0.0, 0.0, 0.0, -u2 * x1.transpose();
    }
  };
  Eigen::Matrix<double, 9, 1> h;
  if (num_points == 4) {
    // Minimal case, run thousands of times per pair: the null vector of the 8x9 system from a
    // fixed-size full-pivoting QR of its transpose (the last column of Q) is as accurate as an
    // SVD and several times faster.
    Eigen::Matrix<double, 8, 9> A;
    fill_rows(&A);
    const Eigen::FullPivHouseholderQR<Eigen::Matrix<double, 9, 8>> qr(A.transpose());
    const auto& R = qr.matrixQR();
    if (!(std::abs(R(7, 7)) > kRankTolerance * std::abs(R(0, 0)))) return;  // Rank < 8.
    const Eigen::Matrix<double, 9, 9> Q = qr.matrixQ();
    h = Q.col(8);
  } else {
    Eigen::Matrix<double, Eigen::Dynamic, 9> A(2 * num_points, 9);
    fill_rows(&A);
    const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 9>> svd(A, Eigen::ComputeFullV);
    const auto& s = svd.singularValues();
    if (!(s(7) > kRankTolerance * s(0))) return;  // Solution not unique.
    h = svd.matrixV().col(8);
  }

  const Eigen::Matrix3d H_normalized =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(h.data());
  // A (near-)singular map cannot relate two views of a plane; it comes from a degenerate
  // sample such as three collinear points mapped onto a line.
  const Eigen::Vector3d sh = H_normalized.jacobiSvd().singularValues();
  if (!(sh(2) > 1e-8 * sh(0))) return;

  const Eigen::Matrix3d H = T2.inverse() * H_normalized * T1;
  if (!H.allFinite()) return;
  models->push_back(H / H.norm());
}

void HomographyMatrixEstimator::Residuals(const std::vector<X_t>& points1,
                                          const std::vector<Y_t>& points2,
                                          const M_t& H,
                                          std::vector<double>* residuals) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_NOTNULL(residuals);
  residuals->resize(points1.size());
  Eigen::Matrix3d H_inv;
  bool invertible = false;
  H.computeInverseWithCheck(H_inv, invertible, /*absDeterminantThreshold=*/0.0);
  if (!invertible || !H_inv.allFinite()) {
    std::fill(residuals->begin(), residuals->end(), kMaxResidual);
    return;
  }
  for (std::size_t i = 0; i < points1.size(); ++i) {
    const Eigen::Vector3d forward = H * points1[i].homogeneous();
    const Eigen::Vector3d backward = H_inv * points2[i].homogeneous();
    if (forward.z() == 0.0 || backward.z() == 0.0) {
      (*residuals)[i] = kMaxResidual;
      continue;
    }
    const double r = (points2[i] - forward.hnormalized()).squaredNorm() +
                     (points1[i] - backward.hnormalized()).squaredNorm();
    (*residuals)[i] = std::isfinite(r) ? r : kMaxResidual;
  }
}

void ComputeHomographySquaredSampsonError(const std::vector<Eigen::Vector2d>& points1,
                                          const std::vector<Eigen::Vector2d>& points2,
                                          const Eigen::Matrix3d& H,
                                          std::vector<double>* residuals) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_NOTNULL(residuals);
  residuals->resize(points1.size());
  for (std::size_t i = 0; i < points1.size(); ++i) {
    const Eigen::Vector3d x1 = points1[i].homogeneous();
    const double u2 = points2[i].x(), v2 = points2[i].y();
    const Eigen::Vector3d Hx1 = H * x1;
    // Algebraic residuals e = (h1.x1 - u2 h3.x1, h2.x1 - v2 h3.x1) and their Jacobian with
    // respect to (u1, v1, u2, v2).
    const Eigen::Vector2d e(Hx1(0) - u2 * Hx1(2), Hx1(1) - v2 * Hx1(2));
    Eigen::Matrix<double, 2, 4> J;
    J << H(0, 0) - u2 * H(2, 0), H(0, 1) - u2 * H(2, 1), -Hx1(2), 0.0,  //
        H(1, 0) - v2 * H(2, 0), H(1, 1) - v2 * H(2, 1), 0.0, -Hx1(2);
    const Eigen::Matrix2d JJt = J * J.transpose();
    const double det = JJt.determinant();
    if (!(std::abs(det) > 0.0)) {
      (*residuals)[i] = kMaxResidual;
      continue;
    }
    const double r = e.dot(JJt.inverse() * e);
    (*residuals)[i] = std::isfinite(r) && r >= 0.0 ? r : kMaxResidual;
  }
}

}  // namespace reconduit
