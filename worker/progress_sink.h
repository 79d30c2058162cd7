// Writes one job run's progress and log lines to the job store, throttled.
//
// A stage may report progress thousands of times a second and log a line per photo; the status
// page needs neither. The sink keeps the newest progress figures and writes them at most once
// per `progress_interval` (stage starts and ends are written at once), and passes log lines
// through a token bucket (`event_burst` lines at once, then `events_per_second`), so that a
// chatty stage cannot flood the database. Lines over the budget are counted and summarised in
// one "N log lines not recorded" event. Nothing is lost from the worker's own stderr log: the
// job runner forwards every line there as well.
//
// Log lines arrive through AddLogLine from the process-wide log sink, which runs with the
// logging lock held. AddLogLine therefore only queues; the queue is written by Flush(), called
// by the job runner's threads (progress callbacks, the heartbeat thread, stage ends). A store
// call may itself log (a busy retry), which must not happen under the logging lock.
//
// A store answer of kFailedPrecondition means this worker no longer holds the job's lease
// (another worker may run it by now): the sink stops writing and calls `on_lease_lost` once.
// Other store errors (a busy database) are logged and the write is retried at the next flush
// where that makes sense (progress, events); they never stop the job.
//
// Thread-safety: every method may be called from any thread. Store writes are serialised, so
// events keep their order.
#ifndef RECONDUIT_WORKER_PROGRESS_SINK_H_
#define RECONDUIT_WORKER_PROGRESS_SINK_H_

#include "core/util/logging.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include "store/job_store.h"
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

namespace reconduit {

struct ProgressSinkOptions {
  // At most one throttled progress write per interval. One write per second keeps a status page
  // live while costing one small transaction (and one WAL fsync) per second at most.
  std::chrono::milliseconds progress_interval{1000};
  // Log lines recorded as events: up to `event_burst` at once, refilled at `events_per_second`.
  // A stage's handful of summary lines always fits; a per-item log in a loop over 10,000
  // photos does not, and is summarised instead.
  double events_per_second = 5.0;
  int event_burst = 50;
  // Longer log lines are cut to this many bytes (with "...").
  std::size_t max_message_bytes = 2000;

  // False, with a message naming the field, for out-of-range values.
  bool Check(std::string* error) const;
};

class ProgressSink {
 public:
  // Does NOT take ownership of `store`, which must outlive the sink. `job_id` must be held by
  // `worker_id` (claimed) while the sink writes.
  ProgressSink(JobStore& store,
               std::string job_id,
               std::string worker_id,
               ProgressSinkOptions options = {});
  ProgressSink(const ProgressSink&) = delete;
  ProgressSink& operator=(const ProgressSink&) = delete;

  // Called once, from the thread whose write found the lease lost. Set before the first write.
  void SetOnLeaseLost(std::function<void()> on_lease_lost);

  // A stage begins: writes stage, overall progress and the stage's progress patch at once
  // (after any queued events).
  // @param stage_patch  merged into stage_progress[stage], e.g. {"progress": 0, "title": ...}.
  void StageStarted(const std::string& stage, double overall, nlohmann::json stage_patch);

  // Progress inside a stage: kept, written when `progress_interval` has passed since the last
  // write (or at the next Flush). Overall progress never goes backwards within a run.
  void StageProgress(const std::string& stage, double overall, nlohmann::json stage_patch);

  // A stage ended: writes its final figures and its counts (may be empty) at once.
  void StageEnded(const std::string& stage,
                  double overall,
                  nlohmann::json stage_patch,
                  const JobCounts& counts);

  // Records that `stage`'s output is complete (JobStore::MarkStageFinished), after the queued
  // events. @return the store's answer.
  Status MarkStageFinished(const std::string& stage, double seconds);

  // Queues an event of the worker's own (stage start and end, warnings): not rate-limited.
  void AddEvent(NewEvent event);

  // Queues a log line of the job (attributed to the current stage), subject to the rate limit.
  // Never calls the store, so it is safe to call from a LogSink.
  void AddLogLine(LogLevel level, std::string_view message);

  // Writes the pending progress (if any) and the queued events. Never throws.
  void Flush();

  // Writes everything pending (progress regardless of the throttle, then events) and stops
  // writing: later calls only queue. The job runner calls it right before the job's final state
  // is written, so that no progress write lands after it (the store would refuse it anyway).
  void Close();

  // True once a write found that the worker no longer holds the lease.
  bool lease_lost() const { return lease_lost_.load(); }

  // The overall progress last reported, in [0, 1].
  double overall() const;

  // Log lines dropped by the rate limit so far.
  std::int64_t dropped_log_lines() const;

 private:
  // Checks a store answer: kFailedPrecondition marks the lease lost. Returns a warning to log
  // (outside every lock) for other failures, empty when none.
  std::string Note(const Status& status, std::string_view what);
  // Writes the pending progress when `force` or due. Caller holds write_mutex_.
  void WriteProgressLocked(bool force, const JobCounts& counts);
  // Writes queued events. Caller holds write_mutex_.
  void WriteEventsLocked();
  void LogOutsideLocks(const std::string& warning);

  JobStore& store_;
  const std::string job_id_;
  const std::string worker_id_;
  const ProgressSinkOptions options_;

  std::function<void()> on_lease_lost_;
  std::atomic<bool> lease_lost_{false};
  // Set by Close(); read under write_mutex_.
  bool closed_ = false;

  // Serialises store writes (and so the order of events).
  std::mutex write_mutex_;

  // Guards everything below.
  mutable std::mutex state_mutex_;
  std::string stage_;
  double overall_ = 0.0;
  // Patch for Job::stage_progress not yet written; null when none.
  nlohmann::json pending_stage_patch_;
  bool progress_pending_ = false;
  std::chrono::steady_clock::time_point next_progress_write_{};
  std::deque<NewEvent> events_;
  // Token bucket for log lines.
  double tokens_ = 0.0;
  std::chrono::steady_clock::time_point tokens_at_{};
  std::int64_t dropped_ = 0;
  std::int64_t dropped_reported_ = 0;
};

}  // namespace reconduit

#endif  // RECONDUIT_WORKER_PROGRESS_SINK_H_
