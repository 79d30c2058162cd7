// Wall-clock timing and process memory figures for stage summaries and benchmarks.
#ifndef RECONDUIT_CORE_UTIL_TIMER_H_
#define RECONDUIT_CORE_UTIL_TIMER_H_

#include <chrono>
#include <cstdint>

namespace reconduit {

// Measures elapsed wall time on the steady clock from construction or Restart().
class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  double ElapsedSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Peak resident set size of this process so far, in bytes (getrusage ru_maxrss).
std::int64_t PeakMemoryBytes();
// Current resident set size of this process, in bytes (/proc/self/statm); 0 if unknown.
std::int64_t CurrentMemoryBytes();

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_TIMER_H_
