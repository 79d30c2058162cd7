// Options shared by every robust estimator in core/optim (RANSAC, LO-RANSAC).
#ifndef RECONDUIT_CORE_OPTIM_RANSAC_OPTIONS_H_
#define RECONDUIT_CORE_OPTIM_RANSAC_OPTIONS_H_

#include <cstddef>
#include <cstdint>
#include <string>

namespace reconduit {

struct RANSACOptions {
  // Largest residual of an inlier, in the units of the estimator's residuals before squaring
  // (pixels for the two-view facades, normalised image units for the calibrated solvers).
  // Estimators return squared residuals; RANSAC compares them with max_error². > 0.
  double max_error = 4.0;

  // Lower bound on the inlier ratio the caller expects; it only caps the number of trials
  // that the dynamic stopping rule may ask for (Fischler & Bolles 1981). (0, 1]
  double min_inlier_ratio = 0.1;

  // Probability that at least one all-inlier sample was drawn when the loop stops. Higher
  // values mean more trials. (0, 1)
  double confidence = 0.9999;

  // The dynamic trial count k = log(1 - confidence) / log(1 - w^s) assumes that every
  // all-inlier sample gives a good model; noise makes that optimistic (Chum et al. 2003), so k
  // is multiplied by this factor, as COLMAP does. >= 1
  double dyn_num_trials_multiplier = 3.0;

  // Bounds on the number of trials (samples drawn). 0 <= min_num_trials <= max_num_trials.
  std::size_t min_num_trials = 0;
  std::size_t max_num_trials = 10000;

  // LO-RANSAC only: how many times the local optimisation re-estimates the model from the
  // inliers of the previous estimate before it stops (it also stops when support stops
  // improving). >= 1
  int max_local_iterations = 10;

  // LO-RANSAC only: trials of the inner RANSAC of Lebeda et al. 2012 ("LO+"): non-minimal
  // samples drawn from the inliers of a new best model, each fitted by the local estimator
  // and then iterated as above. Least squares on ALL inliers can settle on a model bent
  // towards the few mismatches inside the inlier band; subsets that miss them escape that
  // basin. 0 disables the inner RANSAC. >= 0
  int num_local_trials = 10;

  // Seed of the sampler. Runs with the same seed, options and data give identical reports.
  std::uint64_t random_seed = 42;

  // False, with a message naming the field, when a value is out of range.
  bool Check(std::string* error) const;
};

// Number of trials after which an all-inlier sample has been drawn with probability
// `confidence`, given `num_inliers` out of `num_samples` and samples of `sample_size`
// points, multiplied by `multiplier`. Saturates at the largest size_t instead of overflowing.
std::size_t ComputeRANSACNumTrials(std::size_t num_inliers,
                                   std::size_t num_samples,
                                   std::size_t sample_size,
                                   double confidence,
                                   double multiplier);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_RANSAC_OPTIONS_H_
