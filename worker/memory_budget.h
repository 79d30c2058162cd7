// The worker's memory budget: how much of the machine one job may hold, and the watch that
// stops a job going over it before the kernel's OOM killer stops the whole worker.
//
// Stages bound their own memory where they can (SIFT in tiles, one depth map at a time, ...),
// but what a job needs still grows with what clients upload (photos, their size, options).
// A thread samples the process's resident set (one job per process: worker/job_runner.h) every
// `interval`; above the budget it calls `on_over` once, and the job runner cancels the stage
// and fails the job with a message naming the stage and both figures. The worker frees the
// job's memory as the stage unwinds and claims the next job. A stage that allocates much more
// than the budget between two samples or two looks at its cancel token can still be killed by
// the kernel: the budget is a fence below the machine's limit, not a guarantee.
#ifndef RECONDUIT_WORKER_MEMORY_BUDGET_H_
#define RECONDUIT_WORKER_MEMORY_BUDGET_H_

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace reconduit {

// The memory this process may use: the machine's physical memory, or its cgroup's limit
// (cgroup v2 memory.max, v1 memory.limit_in_bytes) when lower; 0 if unknown.
std::int64_t MachineMemoryBytes();

// The default budget of a worker: three quarters of MachineMemoryBytes() (the rest for the
// server, the page cache and other workers' baseline), 0 (none) when that is unknown.
std::int64_t DefaultMemoryBudgetBytes();

// "1.23 GiB" / "456 MiB".
std::string FormatMemory(std::int64_t bytes);

class MemoryWatch {
 public:
  // Samples CurrentMemoryBytes() every `interval` until destroyed; the first sample above
  // `budget_bytes` calls `on_over(resident_bytes)` (on the watch's thread), once. A budget of
  // 0 watches nothing (no thread).
  MemoryWatch(std::int64_t budget_bytes,
              std::chrono::milliseconds interval,
              std::function<void(std::int64_t resident_bytes)> on_over);
  MemoryWatch(const MemoryWatch&) = delete;
  MemoryWatch& operator=(const MemoryWatch&) = delete;
  ~MemoryWatch();

 private:
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace reconduit

#endif  // RECONDUIT_WORKER_MEMORY_BUDGET_H_
