#include "core/estimators/polynomial.h"

#include <Eigen/Eigenvalues>

#include <cmath>

namespace reconduit {

std::vector<double> RealPolynomialRoots(const Eigen::VectorXd& coeffs, double max_imag) {
  std::vector<double> roots;
  if (coeffs.size() == 0 || !coeffs.allFinite()) return roots;
  const double scale = coeffs.cwiseAbs().maxCoeff();
  if (scale == 0.0) return roots;
  Eigen::Index lead = 0;
  while (lead < coeffs.size() && std::abs(coeffs(lead)) <= 1e-14 * scale) ++lead;
  const Eigen::Index degree = coeffs.size() - 1 - lead;
  if (degree <= 0) return roots;
  if (degree == 1) {
    roots.push_back(-coeffs(lead + 1) / coeffs(lead));
    return roots;
  }
  // Companion matrix of the monic polynomial: its eigenvalues are the roots.
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(degree, degree);
  for (Eigen::Index i = 0; i < degree; ++i) {
    companion(0, i) = -coeffs(lead + 1 + i) / coeffs(lead);
  }
  companion.block(1, 0, degree - 1, degree - 1).setIdentity();
  const Eigen::EigenSolver<Eigen::MatrixXd> solver(companion, /*computeEigenvectors=*/false);
  if (solver.info() != Eigen::Success) return roots;
  for (Eigen::Index i = 0; i < degree; ++i) {
    const std::complex<double> root = solver.eigenvalues()(i);
    if (std::abs(root.imag()) <= max_imag * (1.0 + std::abs(root.real()))) {
      roots.push_back(root.real());
    }
  }
  return roots;
}

}  // namespace reconduit
