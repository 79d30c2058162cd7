// Progress reporting for long work, in natural units (images, pairs, iterations).
//
// A stage calls Restart(total, message) when it begins a phase and Advance() per item, from
// any thread. The callback (the worker's database writer, the command line's progress bar)
// is called at most once per `min_interval` for Advance(), and always for Restart(),
// SetMessage() and Finish(), so it may be slow (a database write) without slowing the loop.
// A Progress built without a callback is the null object (OpenMVG's dummy()): it only counts.
//
// Thread-safety: Advance() is lock-free except when a report is due; the callback is never
// called concurrently with itself.
#ifndef RECONDUIT_CORE_UTIL_PROGRESS_H_
#define RECONDUIT_CORE_UTIL_PROGRESS_H_

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

namespace reconduit {

struct ProgressUpdate {
  std::size_t done = 0;
  std::size_t total = 0;
  // done / total in [0, 1]; 0 when total is 0.
  double fraction = 0.0;
  std::string message;
};

class Progress {
 public:
  using Callback = std::function<void(const ProgressUpdate&)>;

  explicit Progress(Callback callback = {},
                    std::chrono::milliseconds min_interval = std::chrono::milliseconds(250));
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Starts a phase of `total` units described by `message`; resets the count. Reports.
  void Restart(std::size_t total, std::string message);
  // Counts `n` more units done (clamped to total). Reports when the interval has passed.
  void Advance(std::size_t n = 1);
  // Changes the message without changing the count. Reports.
  void SetMessage(std::string message);
  // Marks the phase complete (done = total). Reports.
  void Finish();

  std::size_t done() const { return done_.load(); }
  std::size_t total() const { return total_.load(); }
  double fraction() const;
  std::string message() const;

 private:
  void Report(bool force);

  Callback callback_;
  std::chrono::nanoseconds min_interval_;
  std::atomic<std::size_t> done_{0};
  std::atomic<std::size_t> total_{0};
  std::atomic<std::int64_t> next_report_ns_{0};
  mutable std::mutex mutex_;  // Guards message_ and serialises the callback.
  std::string message_;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_UTIL_PROGRESS_H_
