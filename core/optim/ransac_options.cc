#include "core/optim/ransac_options.h"

#include <cmath>
#include <limits>
#include <sstream>

namespace reconduit {
namespace {

bool Fail(std::string* error, const std::string& message) {
  if (error != nullptr) *error = "RANSACOptions: " + message;
  return false;
}

}  // namespace

bool RANSACOptions::Check(std::string* error) const {
  std::ostringstream s;
  if (!(max_error > 0.0) || !std::isfinite(max_error)) {
    s << "max_error must be a finite number > 0, got " << max_error;
    return Fail(error, s.str());
  }
  if (!(min_inlier_ratio > 0.0 && min_inlier_ratio <= 1.0)) {
    s << "min_inlier_ratio must be in (0, 1], got " << min_inlier_ratio;
    return Fail(error, s.str());
  }
  if (!(confidence > 0.0 && confidence < 1.0)) {
    s << "confidence must be in (0, 1), got " << confidence;
    return Fail(error, s.str());
  }
  if (!(dyn_num_trials_multiplier >= 1.0) || !std::isfinite(dyn_num_trials_multiplier)) {
    s << "dyn_num_trials_multiplier must be >= 1, got " << dyn_num_trials_multiplier;
    return Fail(error, s.str());
  }
  if (max_num_trials == 0 || min_num_trials > max_num_trials) {
    s << "need 0 <= min_num_trials <= max_num_trials and max_num_trials > 0, got " << min_num_trials
      << " and " << max_num_trials;
    return Fail(error, s.str());
  }
  if (max_local_iterations < 1) {
    s << "max_local_iterations must be >= 1, got " << max_local_iterations;
    return Fail(error, s.str());
  }
  if (num_local_trials < 0) {
    s << "num_local_trials must be >= 0, got " << num_local_trials;
    return Fail(error, s.str());
  }
  if (error != nullptr) error->clear();
  return true;
}

std::size_t ComputeRANSACNumTrials(std::size_t num_inliers,
                                   std::size_t num_samples,
                                   std::size_t sample_size,
                                   double confidence,
                                   double multiplier) {
  constexpr std::size_t kMax = std::numeric_limits<std::size_t>::max();
  if (num_samples == 0 || num_inliers == 0) return kMax;
  const double inlier_ratio = static_cast<double>(num_inliers) / static_cast<double>(num_samples);
  const double p_all_inliers = std::pow(inlier_ratio, static_cast<double>(sample_size));
  if (p_all_inliers <= 0.0) return kMax;
  if (p_all_inliers >= 1.0) return 1;
  // log1p keeps precision when p_all_inliers is tiny (low inlier ratios).
  const double denom = std::log1p(-p_all_inliers);
  if (denom >= 0.0) return kMax;
  const double trials = std::ceil(std::log(1.0 - confidence) / denom * multiplier);
  if (!(trials < static_cast<double>(kMax))) return kMax;
  return trials < 1.0 ? 1 : static_cast<std::size_t>(trials);
}

}  // namespace reconduit
