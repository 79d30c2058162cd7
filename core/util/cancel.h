// Cooperative cancellation.
//
// A CancelToken is cheap to copy (copies share one flag) and cheap to poll, so long loops can
// check it per item (OpenMVG's hasBeenCanceled) and bundle adjustment can check it per
// iteration through a Ceres IterationCallback. The worker additionally installs a probe that
// looks at the job's cancel flag in the database; the probe is called at most once per
// `min_interval`, whatever the polling rate, so polling stays cheap.
//
// Thread-safety: all methods may be called from any thread.
#ifndef RECONDUIT_CORE_UTIL_CANCEL_H_
#define RECONDUIT_CORE_UTIL_CANCEL_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace reconduit {

// Thrown by CancelToken::ThrowIfCanceled(); stages let it propagate to the runner, which
// turns it into a "canceled" stage result.
class CanceledError : public std::runtime_error {
 public:
  CanceledError() : std::runtime_error("canceled") {}
};

class CancelToken {
 public:
  CancelToken();

  // Asks every holder of this token (and its copies) to stop. Idempotent.
  void RequestCancel() const;

  // True once RequestCancel() was called or the probe answered true.
  bool IsCanceled() const;

  // Throws CanceledError when IsCanceled().
  void ThrowIfCanceled() const;

  // Installs a function asked "should we stop?" at most once per `min_interval`.
  // Replaces any earlier probe. The probe must be thread-safe.
  void SetProbe(std::function<bool()> probe,
                std::chrono::milliseconds min_interval = std::chrono::milliseconds(500)) const;

 private:
  struct State {
    std::atomic<bool> canceled{false};
    std::mutex probe_mutex;
    std::function<bool()> probe;
    std::chrono::milliseconds probe_interval{500};
    std::atomic<std::int64_t> next_probe_ns{0};
  };
  std::shared_ptr<State> state_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_CANCEL_H_
