#include "core/util/cancel.h"

namespace reconduit {
namespace {
std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

CancelToken::CancelToken() : state_(std::make_shared<State>()) {}

void CancelToken::RequestCancel() const { state_->canceled.store(true); }

bool CancelToken::IsCanceled() const {
  if (state_->canceled.load(std::memory_order_relaxed)) return true;
  const std::int64_t now = NowNs();
  if (now < state_->next_probe_ns.load(std::memory_order_relaxed)) return false;
  // Only one thread probes at a time; the others keep going.
  std::unique_lock lock(state_->probe_mutex, std::try_to_lock);
  if (!lock.owns_lock() || !state_->probe) return false;
  state_->next_probe_ns.store(
      now + std::chrono::duration_cast<std::chrono::nanoseconds>(state_->probe_interval).count());
  if (state_->probe()) state_->canceled.store(true);
  return state_->canceled.load();
}

void CancelToken::ThrowIfCanceled() const {
  if (IsCanceled()) throw CanceledError();
}

void CancelToken::SetProbe(std::function<bool()> probe,
                           std::chrono::milliseconds min_interval) const {
  std::lock_guard lock(state_->probe_mutex);
  state_->probe = std::move(probe);
  state_->probe_interval = min_interval;
  state_->next_probe_ns.store(0);
}

}  // namespace reconduit
