#include "core/optim/support_measurement.h"

namespace reconduit {

InlierSupportMeasurer::Support InlierSupportMeasurer::Evaluate(
    const std::vector<double>& squared_residuals, double max_residual) const {
  Support support;
  support.residual_sum = 0.0;
  for (const double r : squared_residuals) {
    // `r <= max_residual` is false for NaN, so NaN residuals are outliers.
    if (r <= max_residual) {
      ++support.num_inliers;
      support.residual_sum += r;
    }
  }
  return support;
}

bool InlierSupportMeasurer::IsLeftBetter(const Support& left, const Support& right) const {
  if (left.num_inliers != right.num_inliers) return left.num_inliers > right.num_inliers;
  return left.residual_sum < right.residual_sum;
}

MEstimatorSupportMeasurer::Support MEstimatorSupportMeasurer::Evaluate(
    const std::vector<double>& squared_residuals, double max_residual) const {
  Support support;
  support.score = 0.0;
  for (const double r : squared_residuals) {
    if (r <= max_residual) {
      ++support.num_inliers;
      support.score += r;
    } else {
      support.score += max_residual;
    }
  }
  return support;
}

bool MEstimatorSupportMeasurer::IsLeftBetter(const Support& left, const Support& right) const {
  return left.score < right.score;
}

}  // namespace reconduit
