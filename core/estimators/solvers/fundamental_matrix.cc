#include "core/estimators/solvers/fundamental_matrix.h"

#include "core/estimators/normalization.h"
#include "core/estimators/polynomial.h"
#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>

namespace reconduit {
namespace {

// Row of the epipolar system for F stored row-major: x2^T F x1 = row . f.
Eigen::Matrix<double, 1, 9> EpipolarRow(const Eigen::Vector2d& x1, const Eigen::Vector2d& x2) {
  Eigen::Matrix<double, 1, 9> row;
  row << x2.x() * x1.x(), x2.x() * x1.y(), x2.x(), x2.y() * x1.x(), x2.y() * x1.y(), x2.y(), x1.x(),
      x1.y(), 1.0;
  return row;
}

Eigen::Matrix3d FromRowMajor(const Eigen::Matrix<double, 9, 1>& f) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(f.data());
}

// F in pixels from F in normalised coordinates: x2n^T Fn x1n = x2^T (T2^T Fn T1) x1.
Eigen::Matrix3d Denormalize(const Eigen::Matrix3d& F_normalized,
                            const Eigen::Matrix3d& T1,
                            const Eigen::Matrix3d& T2) {
  const Eigen::Matrix3d F = T2.transpose() * F_normalized * T1;
  return F / F.norm();
}

// Relative rank tolerance: a singular value below this fraction of the largest one counts as
// zero (noise-free degenerate configurations give ~1e-16 here; any real noise gives far more).
constexpr double kRankTolerance = 1e-10;

}  // namespace

void FundamentalMatrixSevenPointEstimator::Estimate(const std::vector<X_t>& points1,
                                                    const std::vector<Y_t>& points2,
                                                    std::vector<M_t>* models) {
  THROW_CHECK_EQ(points1.size(), 7);
  THROW_CHECK_EQ(points2.size(), 7);
  THROW_CHECK_NOTNULL(models);
  models->clear();

  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!CenterAndNormalizeImagePoints(points1, &n1, &T1) ||
      !CenterAndNormalizeImagePoints(points2, &n2, &T2)) {
    return;
  }

  // Null space of the 7x9 system from a full-pivoting QR of its transpose: the last two
  // columns of Q are orthogonal to the row space. This is as accurate as an SVD here and,
  // being fixed-size, several times faster (the solver runs thousands of times per pair).
  Eigen::Matrix<double, 9, 7> At;
  for (int i = 0; i < 7; ++i) At.col(i) = EpipolarRow(n1[i], n2[i]).transpose();
  const Eigen::FullPivHouseholderQR<Eigen::Matrix<double, 9, 7>> qr(At);
  const auto& R = qr.matrixQR();
  // Full pivoting sorts |R(i, i)| in decreasing order; a zero R(6, 6) means rank < 7.
  if (!(std::abs(R(6, 6)) > kRankTolerance * std::abs(R(0, 0)))) return;
  const Eigen::Matrix<double, 9, 9> Q = qr.matrixQ();
  const Eigen::Matrix<double, 9, 1> f1 = Q.col(7), f2 = Q.col(8);

  const Eigen::Matrix3d F1 = FromRowMajor(f1);
  const Eigen::Matrix3d F2 = FromRowMajor(f2);
  // det(F2 + a (F1 - F2)) is a cubic in a; recover its coefficients from four values.
  const Eigen::Matrix3d D = F1 - F2;
  const auto det_at = [&](double a) { return (F2 + a * D).determinant(); };
  const double p0 = det_at(0.0), p1 = det_at(1.0), pm1 = det_at(-1.0), p2 = det_at(2.0);
  const double c0 = p0;
  const double c2 = 0.5 * (p1 + pm1) - c0;
  const double odd = 0.5 * (p1 - pm1);  // c3 + c1
  const double c3 = (p2 - c0 - 4.0 * c2 - 2.0 * odd) / 6.0;
  const double c1 = odd - c3;

  for (const double a : RealPolynomialRoots(Eigen::Vector4d(c3, c2, c1, c0))) {
    const Eigen::Matrix3d F_normalized = F2 + a * D;
    if (!F_normalized.allFinite() || F_normalized.norm() == 0.0) continue;
    models->push_back(Denormalize(F_normalized, T1, T2));
  }
}

void FundamentalMatrixSevenPointEstimator::Residuals(const std::vector<X_t>& points1,
                                                     const std::vector<Y_t>& points2,
                                                     const M_t& F,
                                                     std::vector<double>* residuals) {
  ComputeSquaredSampsonError(points1, points2, F, residuals);
}

void FundamentalMatrixEightPointEstimator::Estimate(const std::vector<X_t>& points1,
                                                    const std::vector<Y_t>& points2,
                                                    std::vector<M_t>* models) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_GE(points1.size(), 8);
  THROW_CHECK_NOTNULL(models);
  models->clear();

  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!CenterAndNormalizeImagePoints(points1, &n1, &T1) ||
      !CenterAndNormalizeImagePoints(points2, &n2, &T2)) {
    return;
  }

  Eigen::Matrix<double, Eigen::Dynamic, 9> A(points1.size(), 9);
  for (std::size_t i = 0; i < points1.size(); ++i) A.row(i) = EpipolarRow(n1[i], n2[i]);
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 9>> svd(A, Eigen::ComputeFullV);
  const auto& s = svd.singularValues();
  if (!(s(7) > kRankTolerance * s(0))) return;  // Solution not unique.

  // Closest rank-2 matrix in the Frobenius norm (H&Z §11.1.1).
  const Eigen::Matrix3d F_full = FromRowMajor(svd.matrixV().col(8));
  Eigen::JacobiSVD<Eigen::Matrix3d> svd_f(F_full, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sf = svd_f.singularValues();
  sf(2) = 0.0;
  const Eigen::Matrix3d F_normalized =
      svd_f.matrixU() * sf.asDiagonal() * svd_f.matrixV().transpose();
  if (!F_normalized.allFinite()) return;
  models->push_back(Denormalize(F_normalized, T1, T2));
}

void FundamentalMatrixEightPointEstimator::Refine(const std::vector<X_t>& points1,
                                                  const std::vector<Y_t>& points2,
                                                  M_t* F) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_NOTNULL(F);
  if (points1.size() < 8) return;
  std::vector<Eigen::Vector2d> n1, n2;
  Eigen::Matrix3d T1, T2;
  if (!CenterAndNormalizeImagePoints(points1, &n1, &T1) ||
      !CenterAndNormalizeImagePoints(points2, &n2, &T2)) {
    return;
  }
  // F = T2^T Fn T1, so Fn = T2^-T F T1^-1.
  Eigen::Matrix3d Fn = T2.inverse().transpose() * (*F) * T1.inverse();
  if (!Fn.allFinite() || Fn.norm() == 0.0) return;
  Fn /= Fn.norm();

  constexpr int kMaxIterations = 10;
  constexpr double kTukeyThreshold = 4.685;  // In robust standard deviations (95 % efficient).
  const std::size_t num_points = n1.size();
  std::vector<double> distances(num_points), inverse_gradient_norms(num_points);
  Eigen::Matrix<double, Eigen::Dynamic, 9> A(num_points, 9);
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    for (std::size_t i = 0; i < num_points; ++i) {
      const Eigen::Vector3d x1 = n1[i].homogeneous(), x2 = n2[i].homogeneous();
      const Eigen::Vector3d Fx1 = Fn * x1, Ftx2 = Fn.transpose() * x2;
      const double gradient_norm =
          std::sqrt(Fx1.head<2>().squaredNorm() + Ftx2.head<2>().squaredNorm());
      inverse_gradient_norms[i] = gradient_norm > 0.0 ? 1.0 / gradient_norm : 0.0;
      distances[i] = std::abs(x2.dot(Fx1)) * inverse_gradient_norms[i];
    }
    std::vector<double> sorted = distances;
    std::nth_element(sorted.begin(), sorted.begin() + num_points / 2, sorted.end());
    const double tukey_scale = kTukeyThreshold * 1.4826 * sorted[num_points / 2];
    std::size_t num_weighted = 0;
    for (std::size_t i = 0; i < num_points; ++i) {
      // Tukey's biweight: mismatches more than ~4.7 robust sigmas off get no weight at all.
      double tukey = 1.0;
      if (tukey_scale > 0.0) {
        const double u = distances[i] / tukey_scale;
        tukey = u < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
      }
      num_weighted += tukey > 0.0 ? 1 : 0;
      A.row(i) = std::sqrt(tukey) * inverse_gradient_norms[i] * EpipolarRow(n1[i], n2[i]);
    }
    if (num_weighted < 8) return;
    const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 9>> svd(A, Eigen::ComputeFullV);
    const auto& s = svd.singularValues();
    if (!(s(7) > kRankTolerance * s(0))) return;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd_f(FromRowMajor(svd.matrixV().col(8)),
                                            Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Vector3d sf = svd_f.singularValues();
    sf(2) = 0.0;
    Eigen::Matrix3d Fn_new = svd_f.matrixU() * sf.asDiagonal() * svd_f.matrixV().transpose();
    if (!Fn_new.allFinite() || Fn_new.norm() == 0.0) return;
    Fn_new /= Fn_new.norm();
    if ((Fn_new + Fn).norm() < (Fn_new - Fn).norm()) Fn_new = -Fn_new;  // Same sign.
    const double change = (Fn_new - Fn).norm();
    Fn = Fn_new;
    if (change < 1e-12) break;
  }
  *F = Denormalize(Fn, T1, T2);
}

void FundamentalMatrixEightPointEstimator::Residuals(const std::vector<X_t>& points1,
                                                     const std::vector<Y_t>& points2,
                                                     const M_t& F,
                                                     std::vector<double>* residuals) {
  ComputeSquaredSampsonError(points1, points2, F, residuals);
}

void ComputeSquaredSampsonError(const std::vector<Eigen::Vector2d>& points1,
                                const std::vector<Eigen::Vector2d>& points2,
                                const Eigen::Matrix3d& F,
                                std::vector<double>* residuals) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  THROW_CHECK_NOTNULL(residuals);
  residuals->resize(points1.size());
  for (std::size_t i = 0; i < points1.size(); ++i) {
    const Eigen::Vector3d x1 = points1[i].homogeneous();
    const Eigen::Vector3d x2 = points2[i].homogeneous();
    const Eigen::Vector3d Fx1 = F * x1;
    const Eigen::Vector3d Ftx2 = F.transpose() * x2;
    const double numerator = x2.dot(Fx1);
    const double denominator = Fx1.head<2>().squaredNorm() + Ftx2.head<2>().squaredNorm();
    (*residuals)[i] = denominator > 0.0 ? numerator * numerator / denominator
                                        : std::numeric_limits<double>::max();
  }
}

}  // namespace reconduit
