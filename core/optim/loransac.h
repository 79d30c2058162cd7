// Locally optimised RANSAC (Chum, Matas & Kittler 2003, "Locally Optimized RANSAC", DAGM;
// Lebeda, Matas & Chum 2012, "Fixing the Locally Optimized RANSAC", BMVC).
//
// Each time a minimal sample gives a new best model, the model is re-estimated from all its
// inliers with a non-minimal LocalEstimator (e.g. the normalised 8-point algorithm after the
// 7-point one), and again from the inliers of the result, until the support stops improving
// or RANSACOptions::max_local_iterations is reached. Then an inner RANSAC draws
// RANSACOptions::num_local_trials non-minimal samples from those inliers and iterates each
// the same way (Lebeda et al.'s LO+), keeping whatever scores best. When LocalEstimator also has
//
//   static void Refine(const std::vector<X_t>& X, const std::vector<Y_t>& Y, M_t* model);
//
// (a non-linear polish from an initial model, detected at compile time), each local estimate
// and the current best model are refined on the inliers too. Minimal-sample models are noisy,
// so this finds more inliers, needs fewer trials (a better inlier ratio lowers the dynamic
// trial count) and returns a model fitted to all inliers, not to s of them.
//
// Contract of LocalEstimator: the Estimator contract of ransac.h with the same X_t, Y_t, M_t;
// its kMinNumSamples is the smallest inlier set it accepts.
#ifndef RECONDUIT_CORE_OPTIM_LORANSAC_H_
#define RECONDUIT_CORE_OPTIM_LORANSAC_H_

#include "core/optim/ransac.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

namespace reconduit {

// True when LocalEstimator has a static Refine(X, Y, M_t*).
template <typename LocalEstimator>
constexpr bool kHasRefine = requires(const std::vector<typename LocalEstimator::X_t>& X,
                                     const std::vector<typename LocalEstimator::Y_t>& Y,
                                     typename LocalEstimator::M_t* model) {
  LocalEstimator::Refine(X, Y, model);
};

// Thread-safety: as RANSAC (Estimate() is const and stateless).
template <typename Estimator,
          typename LocalEstimator,
          typename SupportMeasurer = InlierSupportMeasurer,
          typename Sampler = RandomSampler>
class LORANSAC {
 public:
  using X_t = typename Estimator::X_t;
  using Y_t = typename Estimator::Y_t;
  using M_t = typename Estimator::M_t;
  using Support = typename SupportMeasurer::Support;
  using Report = RANSACReport<M_t, Support>;
  static_assert(std::is_same_v<X_t, typename LocalEstimator::X_t> &&
                    std::is_same_v<Y_t, typename LocalEstimator::Y_t> &&
                    std::is_same_v<M_t, typename LocalEstimator::M_t>,
                "Estimator and LocalEstimator must share X_t, Y_t and M_t");

  // Throws CheckError when !options.Check().
  explicit LORANSAC(const RANSACOptions& options) : options_(options) {
    std::string error;
    THROW_CHECK(options_.Check(&error)) << error;
  }

  // As RANSAC::Estimate, with local optimisation of every new best model.
  Report Estimate(const std::vector<X_t>& X,
                  const std::vector<Y_t>& Y,
                  const CancelToken* cancel = nullptr) const {
    // Each local optimisation seeds its inner sampler from the options' seed and a call
    // counter, so runs stay reproducible.
    std::uint64_t num_local_calls = 0;
    return internal::RunRANSAC<Estimator, SupportMeasurer, Sampler>(
        options_, X, Y, cancel,
        [this, &num_local_calls](const std::vector<X_t>& X_all, const std::vector<Y_t>& Y_all,
                                 double max_residual, M_t* best_model, Support* best_support) {
          LocalOptimize(X_all, Y_all, max_residual,
                        options_.random_seed + 0x9E3779B97F4A7C15ULL * ++num_local_calls,
                        best_model, best_support);
        });
  }

  const RANSACOptions& options() const { return options_; }

 private:
  // Iterated least squares (and Refine) on the inliers of *model, while support improves.
  void IterateLeastSquares(const std::vector<X_t>& X,
                           const std::vector<Y_t>& Y,
                           double max_residual,
                           M_t* model,
                           Support* support) const {
    const SupportMeasurer measurer;
    std::vector<double> residuals;
    std::vector<X_t> X_inliers;
    std::vector<Y_t> Y_inliers;
    std::vector<M_t> candidates;
    for (int iteration = 0; iteration < options_.max_local_iterations; ++iteration) {
      Estimator::Residuals(X, Y, *model, &residuals);
      X_inliers.clear();
      Y_inliers.clear();
      for (std::size_t i = 0; i < X.size(); ++i) {
        if (residuals[i] <= max_residual) {
          X_inliers.push_back(X[i]);
          Y_inliers.push_back(Y[i]);
        }
      }
      if (X_inliers.size() < static_cast<std::size_t>(LocalEstimator::kMinNumSamples)) return;

      candidates.clear();
      LocalEstimator::Estimate(X_inliers, Y_inliers, &candidates);
      if constexpr (kHasRefine<LocalEstimator>) {
        for (M_t& candidate : candidates) LocalEstimator::Refine(X_inliers, Y_inliers, &candidate);
        candidates.push_back(*model);
        LocalEstimator::Refine(X_inliers, Y_inliers, &candidates.back());
      }

      bool improved = false;
      for (const M_t& candidate : candidates) {
        // Scored with Estimator's residuals, exactly as the main loop scores samples.
        Estimator::Residuals(X, Y, candidate, &residuals);
        const Support candidate_support = measurer.Evaluate(residuals, max_residual);
        if (measurer.IsLeftBetter(candidate_support, *support)) {
          *model = candidate;
          *support = candidate_support;
          improved = true;
        }
      }
      if (!improved) return;
    }
  }

  void LocalOptimize(const std::vector<X_t>& X,
                     const std::vector<Y_t>& Y,
                     double max_residual,
                     std::uint64_t seed,
                     M_t* best_model,
                     Support* best_support) const {
    IterateLeastSquares(X, Y, max_residual, best_model, best_support);

    // Inner RANSAC (Lebeda et al. 2012): samples of up to 2x the minimal size (at most half of
    // the inliers, at least the local estimator's minimum) from the current inliers.
    std::vector<double> residuals;
    Estimator::Residuals(X, Y, *best_model, &residuals);
    std::vector<std::size_t> inliers;
    for (std::size_t i = 0; i < X.size(); ++i) {
      if (residuals[i] <= max_residual) inliers.push_back(i);
    }
    const std::size_t sample_size = std::max<std::size_t>(
        LocalEstimator::kMinNumSamples,
        std::min<std::size_t>(2 * Estimator::kMinNumSamples, inliers.size() / 2));
    if (options_.num_local_trials == 0 || inliers.size() < 2 * sample_size) return;

    const SupportMeasurer measurer;
    Sampler sampler(sample_size, seed);
    sampler.Initialize(inliers.size());
    std::vector<std::size_t> sample;
    std::vector<X_t> X_sample(sample_size);
    std::vector<Y_t> Y_sample(sample_size);
    std::vector<M_t> candidates;
    for (int trial = 0; trial < options_.num_local_trials; ++trial) {
      sampler.Sample(&sample);
      for (std::size_t i = 0; i < sample_size; ++i) {
        X_sample[i] = X[inliers[sample[i]]];
        Y_sample[i] = Y[inliers[sample[i]]];
      }
      candidates.clear();
      LocalEstimator::Estimate(X_sample, Y_sample, &candidates);
      for (M_t& candidate : candidates) {
        Estimator::Residuals(X, Y, candidate, &residuals);
        Support support = measurer.Evaluate(residuals, max_residual);
        IterateLeastSquares(X, Y, max_residual, &candidate, &support);
        if (measurer.IsLeftBetter(support, *best_support)) {
          *best_model = candidate;
          *best_support = support;
        }
      }
    }
  }

  RANSACOptions options_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_LORANSAC_H_
