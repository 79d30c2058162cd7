#include "core/optim/random_sampler.h"

#include "core/util/logging.h"

#include <algorithm>
#include <limits>
#include <numeric>
#include <utility>

namespace reconduit {

RandomSampler::RandomSampler(std::size_t num_samples, std::uint64_t seed)
    : num_samples_(num_samples), rng_(seed) {
  THROW_CHECK_GT(num_samples, 0);
}

void RandomSampler::Initialize(std::size_t num_total_samples) {
  THROW_CHECK_GE(num_total_samples, num_samples_);
  num_total_samples_ = num_total_samples;
  pool_.resize(num_total_samples);
  std::iota(pool_.begin(), pool_.end(), std::size_t{0});
}

std::size_t RandomSampler::MaxNumSamples() const {
  // Binomial coefficient C(n, k), computed incrementally; each partial product
  // C(n - k + i, i) is an integer, so the division is exact.
  constexpr std::size_t kMax = std::numeric_limits<std::size_t>::max();
  const std::size_t n = num_total_samples_;
  const std::size_t k = std::min(num_samples_, n - num_samples_);
  std::size_t result = 1;
  for (std::size_t i = 1; i <= k; ++i) {
    const std::size_t factor = n - k + i;
    if (result > kMax / factor) return kMax;
    result = result * factor / i;
  }
  return result;
}

std::size_t RandomSampler::UniformIndex(std::size_t bound) {
  // Reject the top partial block of the 64-bit range so that every residue is equally likely.
  const std::uint64_t range = static_cast<std::uint64_t>(bound);
  const std::uint64_t limit =
      std::numeric_limits<std::uint64_t>::max() - std::numeric_limits<std::uint64_t>::max() % range;
  std::uint64_t value;
  do {
    value = rng_();
  } while (value >= limit);
  return static_cast<std::size_t>(value % range);
}

void RandomSampler::Sample(std::vector<std::size_t>* sample) {
  THROW_CHECK_NOTNULL(sample);
  THROW_CHECK_EQ(pool_.size(), num_total_samples_) << "Initialize() was not called";
  THROW_CHECK_GE(num_total_samples_, num_samples_);
  sample->resize(num_samples_);
  // Partial Fisher-Yates: the first num_samples_ slots of the pool become the sample. The pool
  // stays a permutation, so later draws stay uniform without resetting it.
  for (std::size_t i = 0; i < num_samples_; ++i) {
    const std::size_t j = i + UniformIndex(num_total_samples_ - i);
    std::swap(pool_[i], pool_[j]);
    (*sample)[i] = pool_[i];
  }
}

}  // namespace reconduit
