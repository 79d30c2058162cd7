#include "core/util/timer.h"

#include <algorithm>
#include <atomic>
#include <fcntl.h>
#include <fstream>
#include <mutex>
#include <optional>
#include <string>
#include <sys/resource.h>
#include <unistd.h>

namespace reconduit {
namespace {

// The process's peak before the latest reset of the kernel's mark, and how many resets there
// were (a stretch whose reset is no longer the latest has lost its own mark).
std::mutex g_reset_mutex;
std::atomic<std::int64_t> g_peak_before_reset{0};
std::atomic<std::uint64_t> g_resets{0};

// ru_maxrss: the kernel's high-water mark of the resident set (Linux reports KiB).
std::int64_t KernelPeakBytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return static_cast<std::int64_t>(usage.ru_maxrss) * 1024;
}

// VmHWM of /proc/self/status in bytes; nullopt when unreadable.
std::optional<std::int64_t> HighWaterMarkBytes() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmHWM:", 0) == 0) {
      try {
        return std::stoll(line.substr(6)) * 1024;  // "VmHWM:    1234 kB".
      } catch (const std::exception&) {
        return std::nullopt;
      }
    }
  }
  return std::nullopt;
}

// Writes "5" to /proc/self/clear_refs: the kernel's mark becomes the current resident size.
bool ResetHighWaterMark() {
  const int fd = open("/proc/self/clear_refs", O_WRONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool written = write(fd, "5", 1) == 1;
  close(fd);
  return written;
}

}  // namespace

std::int64_t PeakMemoryBytes() {
  // ru_maxrss and VmHWM read the same mark but may differ by a few pages (the kernel's
  // resident counters are cached per thread): the larger keeps a stage's own peak, read first,
  // from exceeding the process's.
  return std::max(
      {g_peak_before_reset.load(), KernelPeakBytes(), HighWaterMarkBytes().value_or(0)});
}

std::int64_t CurrentMemoryBytes() {
  std::ifstream statm("/proc/self/statm");
  std::int64_t size_pages = 0, resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return 0;
  return resident_pages * static_cast<std::int64_t>(sysconf(_SC_PAGESIZE));
}

StagePeakMemory::StagePeakMemory() {
  const std::lock_guard<std::mutex> lock(g_reset_mutex);
  // Memory that peaks and is freed between this read and the reset escapes both figures; the
  // window is two system calls long.
  const std::int64_t peak = PeakMemoryBytes();
  if (!HighWaterMarkBytes() || !ResetHighWaterMark()) return;
  g_peak_before_reset.store(peak);
  reset_ = true;
  generation_ = ++g_resets;
}

bool StagePeakMemory::Own() const { return reset_ && g_resets.load() == generation_; }

std::int64_t StagePeakMemory::PeakBytes() const {
  if (!Own()) return PeakMemoryBytes();
  return HighWaterMarkBytes().value_or(PeakMemoryBytes());
}

}  // namespace reconduit
