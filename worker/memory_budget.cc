#include "worker/memory_budget.h"

#include "core/util/timer.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

// A cgroup limit file's value in bytes; 0 for "max", a missing file or a value that is not a
// limit (cgroup v1 writes about 2^63 for "none").
std::int64_t CgroupLimit(const char* path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  try {
    const long long value = std::stoll(text);
    return value > 0 && value < (std::int64_t{1} << 60) ? value : 0;
  } catch (const std::exception&) {
    return 0;
  }
}

}  // namespace

std::int64_t MachineMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGE_SIZE);
  std::int64_t bytes = pages > 0 && page_size > 0 ? std::int64_t{pages} * page_size : 0;
  for (const char* path :
       {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    const std::int64_t limit = CgroupLimit(path);
    if (limit > 0) bytes = bytes > 0 ? std::min(bytes, limit) : limit;
  }
  return bytes;
}

std::int64_t DefaultMemoryBudgetBytes() { return MachineMemoryBytes() / 4 * 3; }

std::string FormatMemory(std::int64_t bytes) {
  char text[32];
  const double mib = static_cast<double>(bytes) / (1 << 20);
  if (mib >= 1024.0) {
    std::snprintf(text, sizeof(text), "%.2f GiB", mib / 1024.0);
  } else {
    std::snprintf(text, sizeof(text), "%.0f MiB", mib);
  }
  return text;
}

MemoryWatch::MemoryWatch(std::int64_t budget_bytes,
                         std::chrono::milliseconds interval,
                         std::function<void(std::int64_t)> on_over) {
  if (budget_bytes <= 0) return;
  thread_ = std::thread([this, budget_bytes, interval, on_over = std::move(on_over)] {
    std::unique_lock lock(mutex_);
    while (!stopping_) {
      const std::int64_t resident = CurrentMemoryBytes();
      if (resident > budget_bytes) {
        lock.unlock();
        on_over(resident);
        return;
      }
      wake_.wait_for(lock, interval, [this] { return stopping_; });
    }
  });
}

MemoryWatch::~MemoryWatch() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

}  // namespace reconduit
