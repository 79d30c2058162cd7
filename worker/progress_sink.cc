#include "worker/progress_sink.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace reconduit {
namespace {

using Clock = std::chrono::steady_clock;

// Adds `patch` to `*pending` as RFC 7396 does (the store applies the patches the same way).
void MergeInto(nlohmann::json* pending, const nlohmann::json& patch) {
  if (patch.is_null()) return;
  if (pending->is_null()) {
    *pending = patch;
  } else {
    pending->merge_patch(patch);
  }
}

}  // namespace

bool ProgressSinkOptions::Check(std::string* error) const {
  if (progress_interval.count() < 0) {
    *error = "progress_interval must be >= 0";
    return false;
  }
  if (!(events_per_second > 0.0) || !std::isfinite(events_per_second)) {
    *error = "events_per_second must be > 0";
    return false;
  }
  if (event_burst < 1) {
    *error = "event_burst must be >= 1";
    return false;
  }
  if (max_message_bytes < 16) {
    *error = "max_message_bytes must be >= 16";
    return false;
  }
  return true;
}

ProgressSink::ProgressSink(JobStore& store,
                           std::string job_id,
                           std::string worker_id,
                           ProgressSinkOptions options)
    : store_(store),
      job_id_(std::move(job_id)),
      worker_id_(std::move(worker_id)),
      options_(options),
      tokens_(options.event_burst),
      tokens_at_(Clock::now()) {
  std::string error;
  THROW_CHECK(options_.Check(&error)) << error;
}

void ProgressSink::SetOnLeaseLost(std::function<void()> on_lease_lost) {
  on_lease_lost_ = std::move(on_lease_lost);
}

double ProgressSink::overall() const {
  std::lock_guard lock(state_mutex_);
  return overall_;
}

std::int64_t ProgressSink::dropped_log_lines() const {
  std::lock_guard lock(state_mutex_);
  return dropped_;
}

std::string ProgressSink::Note(const Status& status, std::string_view what) {
  if (status.ok()) return "";
  if (status.code() == StatusCode::kFailedPrecondition) {
    // Not ours any more. Only the first writer to notice calls back.
    if (!lease_lost_.exchange(true) && on_lease_lost_) on_lease_lost_();
    return "";
  }
  return "job " + job_id_ + ": cannot " + std::string(what) + ": " + status.ToString();
}

void ProgressSink::LogOutsideLocks(const std::string& warning) {
  if (!warning.empty()) {
    LOG_WARNING << warning;
  }
}

void ProgressSink::StageStarted(const std::string& stage,
                                double overall,
                                nlohmann::json stage_patch) {
  {
    std::lock_guard lock(state_mutex_);
    stage_ = stage;
    overall_ = std::clamp(std::max(overall_, overall), 0.0, 1.0);
    MergeInto(&pending_stage_patch_, nlohmann::json{{stage, std::move(stage_patch)}});
    progress_pending_ = true;
  }
  std::lock_guard write(write_mutex_);
  WriteEventsLocked();
  WriteProgressLocked(/*force=*/true, JobCounts());
}

void ProgressSink::StageProgress(const std::string& stage,
                                 double overall,
                                 nlohmann::json stage_patch) {
  bool due = false;
  {
    std::lock_guard lock(state_mutex_);
    stage_ = stage;
    overall_ = std::clamp(std::max(overall_, overall), 0.0, 1.0);
    MergeInto(&pending_stage_patch_, nlohmann::json{{stage, std::move(stage_patch)}});
    progress_pending_ = true;
    due = Clock::now() >= next_progress_write_;
  }
  if (!due) return;
  // A stage's threads must not queue up behind a slow write: whoever holds the write lock
  // writes the newest figures anyway.
  std::unique_lock write(write_mutex_, std::try_to_lock);
  if (!write.owns_lock()) return;
  WriteEventsLocked();
  WriteProgressLocked(/*force=*/false, JobCounts());
}

void ProgressSink::StageEnded(const std::string& stage,
                              double overall,
                              nlohmann::json stage_patch,
                              const JobCounts& counts) {
  {
    std::lock_guard lock(state_mutex_);
    overall_ = std::clamp(std::max(overall_, overall), 0.0, 1.0);
    MergeInto(&pending_stage_patch_, nlohmann::json{{stage, std::move(stage_patch)}});
    progress_pending_ = true;
  }
  std::lock_guard write(write_mutex_);
  WriteEventsLocked();
  WriteProgressLocked(/*force=*/true, counts);
}

Status ProgressSink::MarkStageFinished(const std::string& stage, double seconds) {
  std::lock_guard write(write_mutex_);
  WriteEventsLocked();
  if (lease_lost_) return Status::FailedPrecondition("the lease on job " + job_id_ + " was lost");
  if (closed_) return Status::FailedPrecondition("the run of job " + job_id_ + " is over");
  const Status status = store_.MarkStageFinished(job_id_, worker_id_, stage, seconds);
  LogOutsideLocks(Note(status, "mark stage " + stage + " finished"));
  return status;
}

void ProgressSink::AddEvent(NewEvent event) {
  if (event.message.size() > options_.max_message_bytes) {
    event.message.resize(options_.max_message_bytes - 3);
    event.message += "...";
  }
  std::lock_guard lock(state_mutex_);
  events_.push_back(std::move(event));
}

void ProgressSink::AddLogLine(LogLevel level, std::string_view message) {
  std::lock_guard lock(state_mutex_);
  const Clock::time_point now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - tokens_at_).count();
  tokens_ = std::min<double>(options_.event_burst, tokens_ + elapsed * options_.events_per_second);
  tokens_at_ = now;
  if (tokens_ < 1.0) {
    ++dropped_;
    return;
  }
  tokens_ -= 1.0;
  NewEvent event;
  event.stage = stage_;
  event.level = level;
  event.message = std::string(message.substr(0, options_.max_message_bytes));
  if (event.message.size() < message.size()) {
    event.message.resize(options_.max_message_bytes - 3);
    event.message += "...";
  }
  events_.push_back(std::move(event));
}

void ProgressSink::Flush() {
  try {
    std::lock_guard write(write_mutex_);
    WriteEventsLocked();
    WriteProgressLocked(/*force=*/false, JobCounts());
  } catch (const std::exception& e) {
    LOG_WARNING << "job " << job_id_ << ": cannot write progress: " << e.what();
  }
}

void ProgressSink::Close() {
  try {
    std::lock_guard write(write_mutex_);
    WriteEventsLocked();
    WriteProgressLocked(/*force=*/true, JobCounts());
    closed_ = true;
  } catch (const std::exception& e) {
    LOG_WARNING << "job " << job_id_ << ": cannot write progress: " << e.what();
  }
}

void ProgressSink::WriteProgressLocked(bool force, const JobCounts& counts) {
  if (lease_lost_ || closed_) return;
  if (force && counts.empty()) {
    std::lock_guard lock(state_mutex_);
    if (!progress_pending_) return;  // Nothing new to say.
  }
  JobProgressUpdate update;
  nlohmann::json stage_patch;
  {
    std::lock_guard lock(state_mutex_);
    const Clock::time_point now = Clock::now();
    const bool due = progress_pending_ && now >= next_progress_write_;
    if (!force && !due) return;
    update.stage = stage_;
    update.progress = overall_;
    stage_patch = std::move(pending_stage_patch_);
    pending_stage_patch_ = nullptr;
    progress_pending_ = false;
    next_progress_write_ = now + options_.progress_interval;
  }
  update.stage_progress = stage_patch;
  update.counts = counts;
  const Status status = store_.RecordProgress(job_id_, worker_id_, update);
  if (!status.ok() && !lease_lost_ && status.code() != StatusCode::kFailedPrecondition) {
    // Keep what was not written for the next attempt (newer figures win).
    std::lock_guard lock(state_mutex_);
    nlohmann::json merged = std::move(stage_patch);
    MergeInto(&merged, pending_stage_patch_);
    pending_stage_patch_ = std::move(merged);
    progress_pending_ = true;
  }
  LogOutsideLocks(Note(status, "record progress"));
}

void ProgressSink::WriteEventsLocked() {
  if (closed_) return;
  std::deque<NewEvent> events;
  {
    std::lock_guard lock(state_mutex_);
    events.swap(events_);
    if (dropped_ > dropped_reported_) {
      NewEvent summary;
      summary.stage = stage_;
      summary.level = LogLevel::kWarning;
      summary.message = std::to_string(dropped_ - dropped_reported_) +
                        " log lines not recorded (more than " +
                        std::to_string(options_.event_burst) + " at once); see the worker's log";
      dropped_reported_ = dropped_;
      events.push_back(std::move(summary));
    }
  }
  // Events may be written by a worker that lost the lease (AppendEvent does not check it);
  // they still describe what this worker did with the job.
  while (!events.empty()) {
    const Result<std::int64_t> id = store_.AppendEvent(job_id_, events.front());
    if (!id.ok()) {
      if (id.status().code() == StatusCode::kNotFound) return;  // The job was deleted.
      {
        // Put the rest back in front of anything queued meanwhile, in order.
        std::lock_guard lock(state_mutex_);
        events_.insert(events_.begin(), events.begin(), events.end());
      }
      LogOutsideLocks(Note(id.status(), "record an event"));
      return;
    }
    events.pop_front();
  }
}

}  // namespace reconduit
