// How RANSAC scores a model from its squared residuals.
//
// A measurer turns the squared residuals of every data point into a Support value and says
// which of two supports is better. Both measurers below count the inliers (residual <=
// max_residual), because the dynamic trial count needs the inlier ratio.
#ifndef RECONDUIT_CORE_OPTIM_SUPPORT_MEASUREMENT_H_
#define RECONDUIT_CORE_OPTIM_SUPPORT_MEASUREMENT_H_

#include <cstddef>
#include <limits>
#include <vector>

namespace reconduit {

// Classic RANSAC (Fischler & Bolles 1981): more inliers is better; ties go to the smaller sum
// of inlier residuals. Non-finite residuals count as outliers.
class InlierSupportMeasurer {
 public:
  struct Support {
    std::size_t num_inliers = 0;
    // Sum of the squared residuals of the inliers.
    double residual_sum = std::numeric_limits<double>::max();
  };

  // @param squared_residuals  One squared residual per data point.
  // @param max_residual       Squared inlier threshold (max_error²).
  Support Evaluate(const std::vector<double>& squared_residuals, double max_residual) const;

  // True when `left` is strictly better than `right`.
  bool IsLeftBetter(const Support& left, const Support& right) const;
};

// MSAC (Torr & Zisserman 2000, "MLESAC"): minimises sum_i min(r_i², max_residual), i.e. inliers
// are scored by how well they fit and outliers pay a constant. Less sensitive than inlier
// counting to the exact threshold, and prefers the better of two models with equal counts.
// Non-finite residuals pay the constant.
class MEstimatorSupportMeasurer {
 public:
  struct Support {
    std::size_t num_inliers = 0;
    // sum_i min(r_i², max_residual); lower is better.
    double score = std::numeric_limits<double>::max();
  };

  Support Evaluate(const std::vector<double>& squared_residuals, double max_residual) const;
  bool IsLeftBetter(const Support& left, const Support& right) const;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_SUPPORT_MEASUREMENT_H_
