// ParallelFor: the one way core/ runs independent items on several cores.
//
// Why not a general thread pool or OpenMP: every parallel loop in the pipeline is "N
// independent items" (images, pairs, depth maps), and the machine we size for has 2 cores.
// Spawning threads per loop costs microseconds against items that take milliseconds or more,
// keeps no threads idle between jobs in the worker, and lets exceptions and cancellation
// follow one clear rule: the first exception thrown by any item stops the remaining items
// from starting and is rethrown in the caller once all threads have finished.
#ifndef RECONDUIT_CORE_UTIL_PARALLEL_H_
#define RECONDUIT_CORE_UTIL_PARALLEL_H_

#include <cstddef>
#include <functional>

namespace reconduit {

// Threads to use for a request: `requested` > 0 is taken as is; 0 or less means all
// hardware threads (at least 1). The environment variable RECONDUIT_THREADS, when set to a
// positive number, caps the automatic choice.
int EffectiveNumThreads(int requested);

// Calls fn(i) for every i in [begin, end), on up to `num_threads` threads (see
// EffectiveNumThreads), in an unspecified order. Items are handed out one at a time, so uneven
// item costs balance. Blocks until all started items have returned. If any fn throws, no new
// item starts and the first exception is rethrown here.
void ParallelFor(std::size_t begin,
                 std::size_t end,
                 const std::function<void(std::size_t)>& fn,
                 int num_threads = 0);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_PARALLEL_H_
