// Uniform sampling of minimal sets for RANSAC.
#ifndef RECONDUIT_CORE_OPTIM_RANDOM_SAMPLER_H_
#define RECONDUIT_CORE_OPTIM_RANDOM_SAMPLER_H_

#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

namespace reconduit {

// Draws `num_samples` distinct indices from [0, num_total_samples), uniformly (a partial
// Fisher-Yates shuffle, O(num_samples) per draw). The generator is std::mt19937_64, whose
// output is fixed by the C++ standard, and indices are reduced without
// std::uniform_int_distribution (whose output is implementation-defined), so a seed gives the
// same sequence with every compiler and standard library.
//
// Thread-safety: none; use one sampler per thread.
class RandomSampler {
 public:
  RandomSampler(std::size_t num_samples, std::uint64_t seed);

  // Must be called before Sample(); num_total_samples >= num_samples (throws CheckError).
  void Initialize(std::size_t num_total_samples);

  // Number of distinct subsets C(num_total_samples, num_samples), saturated at the largest
  // size_t. RANSAC caps its trial count with it: with 7 points there is only one subset.
  std::size_t MaxNumSamples() const;

  // Fills `sample` with num_samples distinct indices (resized as needed).
  void Sample(std::vector<std::size_t>* sample);

 private:
  // Uniform integer in [0, bound) by rejection, identical on every platform.
  std::size_t UniformIndex(std::size_t bound);

  std::size_t num_samples_;
  std::size_t num_total_samples_ = 0;
  std::mt19937_64 rng_;
  std::vector<std::size_t> pool_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_RANDOM_SAMPLER_H_
