// Real roots of univariate polynomials, for the minimal solvers.
#ifndef RECONDUIT_CORE_ESTIMATORS_POLYNOMIAL_H_
#define RECONDUIT_CORE_ESTIMATORS_POLYNOMIAL_H_

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// Real roots of c[0] x^n + c[1] x^(n-1) + ... + c[n], from the eigenvalues of the companion
// matrix (Edelman & Murakami 1995: backward stable). Leading coefficients that are zero (or
// below 1e-14 times the largest coefficient) are dropped, lowering the degree. Roots whose
// imaginary part exceeds `max_imag` (relative to 1 + |root|) are discarded; the real parts
// of the rest are returned in no particular order. An all-zero polynomial returns no roots.
std::vector<double> RealPolynomialRoots(const Eigen::VectorXd& coeffs, double max_imag = 1e-8);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_POLYNOMIAL_H_
