// Generic RANSAC (Fischler & Bolles 1981) over a minimal solver, with a pluggable support
// measure and sampler and a dynamic trial count.
//
// This file knows nothing about geometry. An Estimator is a stateless type with
//
//   using X_t = ...;  using Y_t = ...;  using M_t = ...;   // data pair and model types
//   static constexpr int kMinNumSamples = ...;            // points per minimal sample
//   // Fits models to exactly (or, for non-minimal use, at least) kMinNumSamples pairs. May
//   // return zero models (degenerate sample) or several (e.g. the 7-point algorithm's 3).
//   static void Estimate(const std::vector<X_t>& X, const std::vector<Y_t>& Y,
//                        std::vector<M_t>* models);
//   // One SQUARED residual per pair, in the units of RANSACOptions::max_error squared.
//   static void Residuals(const std::vector<X_t>& X, const std::vector<Y_t>& Y,
//                         const M_t& model, std::vector<double>* residuals);
//
// (COLMAP's estimator contract, colmap/optim/ransac.h, and OpenMVG's kernel contract.)
// Typical use:
//
//   RANSAC<LineEstimator> ransac(options);
//   const auto report = ransac.Estimate(xs, ys);
//   if (report.success) Use(report.model, report.inlier_mask);
#ifndef RECONDUIT_CORE_OPTIM_RANSAC_H_
#define RECONDUIT_CORE_OPTIM_RANSAC_H_

#include "core/optim/random_sampler.h"
#include "core/optim/ransac_options.h"
#include "core/optim/support_measurement.h"
#include "core/util/cancel.h"
#include "core/util/logging.h"

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

namespace reconduit {

// The outcome of a robust estimation. A default-constructed report reads as failure
// ("not run"); `model`, `support` and `inlier_mask` are meaningful only when `success`.
template <typename M_t, typename Support>
struct RANSACReport {
  bool success = false;
  // True when the CancelToken stopped the loop (success is then false).
  bool canceled = false;
  // Why the estimation failed; empty on success.
  std::string message = "not run";
  // Samples drawn.
  std::size_t num_trials = 0;
  Support support;
  // One entry per input pair: 1 for an inlier of `model`, else 0.
  std::vector<char> inlier_mask;
  M_t model = DefaultModel();

 private:
  static M_t DefaultModel() {
    if constexpr (requires { M_t::Zero(); }) {
      return M_t::Zero();  // Eigen types are left uninitialised by their default constructor.
    } else {
      return M_t{};
    }
  }
};

namespace internal {

// The loop shared by RANSAC and LORANSAC. `local_optimize(X, Y, max_residual, &model,
// &support)` is called each time a sample gives a new best model and may improve both.
template <typename Estimator, typename SupportMeasurer, typename Sampler, typename LocalOptimizer>
RANSACReport<typename Estimator::M_t, typename SupportMeasurer::Support> RunRANSAC(
    const RANSACOptions& options,
    const std::vector<typename Estimator::X_t>& X,
    const std::vector<typename Estimator::Y_t>& Y,
    const CancelToken* cancel,
    LocalOptimizer&& local_optimize) {
  using M_t = typename Estimator::M_t;
  RANSACReport<M_t, typename SupportMeasurer::Support> report;
  THROW_CHECK_EQ(X.size(), Y.size());
  const std::size_t num_data = X.size();
  constexpr std::size_t kSampleSize = Estimator::kMinNumSamples;
  if (num_data < kSampleSize) {
    report.message = "need at least " + std::to_string(kSampleSize) + " data points, got " +
                     std::to_string(num_data);
    return report;
  }

  const double max_residual = options.max_error * options.max_error;
  Sampler sampler(kSampleSize, options.random_seed);
  sampler.Initialize(num_data);
  const SupportMeasurer measurer;

  // The expected minimum inlier ratio bounds the work, as does the number of distinct samples.
  constexpr std::size_t kRatioReferenceSize = 100000;
  const std::size_t max_num_trials = std::min(
      {options.max_num_trials, sampler.MaxNumSamples(),
       std::max(options.min_num_trials,
                ComputeRANSACNumTrials(
                    static_cast<std::size_t>(kRatioReferenceSize * options.min_inlier_ratio),
                    kRatioReferenceSize, kSampleSize, options.confidence,
                    options.dyn_num_trials_multiplier))});
  std::size_t dyn_max_num_trials = max_num_trials;

  bool have_best = false;
  typename SupportMeasurer::Support best_support;
  M_t best_model = report.model;

  std::vector<std::size_t> sample_idxs;
  std::vector<typename Estimator::X_t> X_sample(kSampleSize);
  std::vector<typename Estimator::Y_t> Y_sample(kSampleSize);
  std::vector<M_t> models;
  std::vector<double> residuals;

  std::size_t trial = 0;
  for (; trial < max_num_trials; ++trial) {
    if (trial >= dyn_max_num_trials && trial >= options.min_num_trials) break;
    if (cancel != nullptr && cancel->IsCanceled()) {
      report.canceled = true;
      report.num_trials = trial;
      report.message = "canceled";
      return report;
    }
    sampler.Sample(&sample_idxs);
    for (std::size_t i = 0; i < kSampleSize; ++i) {
      X_sample[i] = X[sample_idxs[i]];
      Y_sample[i] = Y[sample_idxs[i]];
    }
    models.clear();
    Estimator::Estimate(X_sample, Y_sample, &models);
    for (const M_t& model : models) {
      Estimator::Residuals(X, Y, model, &residuals);
      THROW_CHECK_EQ(residuals.size(), num_data);
      const auto support = measurer.Evaluate(residuals, max_residual);
      if (have_best && !measurer.IsLeftBetter(support, best_support)) continue;
      have_best = true;
      best_model = model;
      best_support = support;
      local_optimize(X, Y, max_residual, &best_model, &best_support);
      dyn_max_num_trials =
          std::min(max_num_trials,
                   ComputeRANSACNumTrials(best_support.num_inliers, num_data, kSampleSize,
                                          options.confidence, options.dyn_num_trials_multiplier));
    }
  }
  report.num_trials = trial;

  if (!have_best || best_support.num_inliers < kSampleSize) {
    report.message = "no model with at least " + std::to_string(kSampleSize) + " inliers in " +
                     std::to_string(trial) + " trials (degenerate data or " +
                     "max_error too small)";
    return report;
  }

  report.success = true;
  report.message.clear();
  report.model = best_model;
  report.support = best_support;
  Estimator::Residuals(X, Y, best_model, &residuals);
  report.inlier_mask.resize(num_data);
  for (std::size_t i = 0; i < num_data; ++i) {
    report.inlier_mask[i] = residuals[i] <= max_residual ? 1 : 0;
  }
  return report;
}

}  // namespace internal

// Plain RANSAC: the best model of any minimal sample, scored by SupportMeasurer.
//
// Thread-safety: Estimate() is const and keeps no state between calls, so one object may be
// used from several threads.
template <typename Estimator,
          typename SupportMeasurer = InlierSupportMeasurer,
          typename Sampler = RandomSampler>
class RANSAC {
 public:
  using X_t = typename Estimator::X_t;
  using Y_t = typename Estimator::Y_t;
  using M_t = typename Estimator::M_t;
  using Report = RANSACReport<M_t, typename SupportMeasurer::Support>;

  // Throws CheckError when !options.Check().
  explicit RANSAC(const RANSACOptions& options) : options_(options) {
    std::string error;
    THROW_CHECK(options_.Check(&error)) << error;
  }

  // Robustly fits a model to the pairs (X[i], Y[i]).
  //
  // @param X, Y    Data pairs; equal sizes (else CheckError).
  // @param cancel  Optional; polled once per trial. The caller keeps ownership.
  // @return        A report; success is false (with a message) when there are fewer than
  //                kMinNumSamples pairs, when no model has kMinNumSamples inliers, or when
  //                canceled. Never throws for degenerate data.
  Report Estimate(const std::vector<X_t>& X,
                  const std::vector<Y_t>& Y,
                  const CancelToken* cancel = nullptr) const {
    return internal::RunRANSAC<Estimator, SupportMeasurer, Sampler>(
        options_, X, Y, cancel,
        [](const std::vector<X_t>&, const std::vector<Y_t>&, double, M_t*,
           typename SupportMeasurer::Support*) {});
  }

  const RANSACOptions& options() const { return options_; }

 private:
  RANSACOptions options_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_RANSAC_H_
