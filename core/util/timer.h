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

// Peak resident set size of this process so far, in bytes: the kernel's high-water mark
// (getrusage ru_maxrss, VmHWM), and the marks StagePeakMemory saw before it reset the kernel's.
std::int64_t PeakMemoryBytes();
// Current resident set size of this process, in bytes (/proc/self/statm); 0 if unknown.
std::int64_t CurrentMemoryBytes();

// The peak resident memory of one stretch of work (a pipeline stage): the high-water mark
// since the stretch began, which includes what the process already held then.
//
// Linux keeps one high-water mark of the resident set per process (VmHWM in /proc/self/status)
// and resets it to the current resident size when "5" is written to /proc/self/clear_refs. The
// constructor does that, so the mark read at the end is the stretch's own. getrusage's
// ru_maxrss is not an independent figure: for a live process the kernel derives it from the
// same mark, and it drops with it (measured on Linux 6.18: 200 MiB touched and freed, reset,
// 20 MiB touched: VmHWM and ru_maxrss both read 23 MiB). So before resetting, the constructor
// folds the mark into the figure PeakMemoryBytes() reports, which therefore stays the whole
// process's peak. Measurements from outside see only the mark since the latest reset: the
// parent's wait4 or `/usr/bin/time -f %M` of a run that reset it (measured: `reconduit
// reconstruct` on kermit peaks at 236 MiB in features; `time` says 104 MiB, the mark of the
// last stages). Read the run's own figure instead (report.json peak_memory_bytes, the command
// line's table).
//
// Where the mark cannot be reset (no /proc, /proc read-only in a sandbox, a kernel without
// clear_refs), or when another stretch began meanwhile and reset it again (stretches do not
// nest: one at a time per process), there is no figure of the stretch's own: PeakBytes() is
// the process's peak and Own() says false, so nobody reads it as the stretch's.
class StagePeakMemory {
 public:
  // Begins the stretch: folds the kernel's mark into PeakMemoryBytes() and resets it.
  StagePeakMemory();
  // The stretch's peak so far, in bytes (or the process's peak when !Own()).
  std::int64_t PeakBytes() const;
  // True when PeakBytes() is the stretch's own high-water mark.
  bool Own() const;

 private:
  bool reset_ = false;
  std::uint64_t generation_ = 0;  // Which reset of the process began this stretch.
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_TIMER_H_
