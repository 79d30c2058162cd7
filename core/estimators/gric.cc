#include "core/estimators/gric.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>

namespace reconduit {

double ComputeGRIC(const std::vector<double>& squared_residuals,
                   double sigma,
                   int data_dim,
                   int model_dim,
                   int num_params) {
  THROW_CHECK_GT(sigma, 0.0);
  THROW_CHECK_GT(data_dim, model_dim);
  THROW_CHECK_GE(model_dim, 0);
  THROW_CHECK_GE(num_params, 0);
  constexpr double kLambda3 = 2.0;
  const double n = static_cast<double>(squared_residuals.size());
  const double r = static_cast<double>(data_dim);
  const double cap = kLambda3 * (data_dim - model_dim);
  const double inv_sigma2 = 1.0 / (sigma * sigma);
  double score = 0.0;
  for (const double e2 : squared_residuals) {
    const double x = e2 * inv_sigma2;
    score += std::isfinite(x) ? std::min(x, cap) : cap;
  }
  const double lambda1 = std::log(r);
  const double lambda2 = n > 0 ? std::log(r * n) : 0.0;
  return score + lambda1 * model_dim * n + lambda2 * num_params;
}

}  // namespace reconduit
