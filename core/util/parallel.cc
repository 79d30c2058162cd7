#include "core/util/parallel.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace reconduit {

int EffectiveNumThreads(int requested) {
  if (requested > 0) return requested;
  int n = static_cast<int>(std::thread::hardware_concurrency());
  if (const char* env = std::getenv("RECONDUIT_THREADS")) {
    const int cap = std::atoi(env);
    if (cap > 0) n = n > 0 ? std::min(n, cap) : cap;
  }
  return std::max(1, n);
}

void ParallelFor(std::size_t begin,
                 std::size_t end,
                 const std::function<void(std::size_t)>& fn,
                 int num_threads) {
  if (begin >= end) return;
  const std::size_t count = end - begin;
  const int threads =
      static_cast<int>(std::min<std::size_t>(count, EffectiveNumThreads(num_threads)));
  if (threads <= 1) {
    for (std::size_t i = begin; i < end; ++i) fn(i);
    return;
  }

  std::atomic<std::size_t> next{begin};
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;

  auto work = [&] {
    while (!failed.load(std::memory_order_relaxed)) {
      const std::size_t i = next.fetch_add(1);
      if (i >= end) return;
      try {
        fn(i);
      } catch (...) {
        std::lock_guard lock(error_mutex);
        if (!first_error) first_error = std::current_exception();
        failed.store(true);
      }
    }
  };

  std::vector<std::jthread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();        // The calling thread works too.
  pool.clear();  // Joins.
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace reconduit
