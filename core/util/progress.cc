#include "core/util/progress.h"

#include <algorithm>

namespace reconduit {
namespace {
std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

Progress::Progress(Callback callback, std::chrono::milliseconds min_interval)
    : callback_(std::move(callback)), min_interval_(min_interval) {}

void Progress::Restart(std::size_t total, std::string message) {
  {
    std::lock_guard lock(mutex_);
    message_ = std::move(message);
  }
  total_.store(total);
  done_.store(0);
  Report(/*force=*/true);
}

void Progress::Advance(std::size_t n) {
  const std::size_t total = total_.load();
  std::size_t current = done_.load();
  std::size_t next;
  do {
    next = std::min(total, current + n);
  } while (!done_.compare_exchange_weak(current, next));
  if (callback_) Report(/*force=*/false);
}

void Progress::SetMessage(std::string message) {
  {
    std::lock_guard lock(mutex_);
    message_ = std::move(message);
  }
  Report(/*force=*/true);
}

void Progress::Finish() {
  done_.store(total_.load());
  Report(/*force=*/true);
}

double Progress::fraction() const {
  const std::size_t total = total_.load();
  if (total == 0) return 0.0;
  return std::min(1.0, static_cast<double>(done_.load()) / static_cast<double>(total));
}

std::string Progress::message() const {
  std::lock_guard lock(mutex_);
  return message_;
}

void Progress::Report(bool force) {
  if (!callback_) return;
  const std::int64_t now = NowNs();
  if (!force && now < next_report_ns_.load(std::memory_order_relaxed)) return;
  std::unique_lock lock(mutex_, std::defer_lock);
  if (force) {
    lock.lock();
  } else if (!lock.try_lock()) {
    return;  // Someone else is reporting right now; this update is not needed.
  }
  next_report_ns_.store(now + min_interval_.count());
  ProgressUpdate update;
  update.done = done_.load();
  update.total = total_.load();
  update.fraction =
      update.total == 0
          ? 0.0
          : std::min(1.0, static_cast<double>(update.done) / static_cast<double>(update.total));
  update.message = message_;
  callback_(update);
}

}  // namespace reconduit
