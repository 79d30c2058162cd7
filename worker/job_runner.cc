#include "worker/job_runner.h"

#include "core/util/logging.h"
#include "core/util/timer.h"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <ctime>
#include <exception>
#include <iostream>
#include <set>
#include <sstream>
#include <thread>
#include <utility>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string Quote(std::string_view text) { return "'" + std::string(text) + "'"; }

std::string FormatSeconds(double seconds) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f s", seconds);
  return text;
}

std::string FormatMiB(std::int64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.0f MiB", static_cast<double>(bytes) / (1024.0 * 1024.0));
  return text;
}

// The default log sink's format (core/util/logging.cc), for when no sink was installed.
void WriteStderrLine(LogLevel level, std::string_view message) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y-%m-%dT%H:%M:%SZ", &tm);
  std::cerr << stamp << ' ' << LogLevelName(level) << ' ' << message << '\n';
}

// Installs a log sink for the duration of a job and restores the previous one.
class ScopedLogSink {
 public:
  explicit ScopedLogSink(LogSink sink) : previous_(SetLogSink(std::move(sink))) {}
  ScopedLogSink(const ScopedLogSink&) = delete;
  ScopedLogSink& operator=(const ScopedLogSink&) = delete;
  ~ScopedLogSink() { SetLogSink(std::move(previous_)); }

 private:
  LogSink previous_;
};

// Status of a Status or a Result<T>.
const Status& StatusOf(const Status& status) { return status; }
template <typename T>
const Status& StatusOf(const Result<T>& result) {
  return result.status();
}

// Retries a final store write while the database is busy or failing: a job whose pipeline
// finished should not go back to the queue because one commit met a locked database.
// Ownership errors (kFailedPrecondition), a deleted job (kNotFound) and kInvalidArgument are
// final answers.
template <typename Fn>
auto RetryStoreWrite(Fn&& fn) {
  auto result = fn();
  std::chrono::milliseconds backoff(200);
  for (int attempt = 1; attempt < 6 && !result.ok(); ++attempt) {
    const StatusCode code = StatusOf(result).code();
    if (code == StatusCode::kFailedPrecondition || code == StatusCode::kNotFound ||
        code == StatusCode::kInvalidArgument) {
      break;
    }
    std::this_thread::sleep_for(backoff);
    backoff *= 2;
    result = fn();
  }
  return result;
}

// The last path component of an uploaded name: display names are never paths.
std::string BaseName(std::string_view name) {
  const std::size_t slash = name.find_last_of("/\\");
  if (slash != std::string_view::npos) name = name.substr(slash + 1);
  if (name == "." || name == "..") return "";
  return std::string(name);
}

bool IsPlainFileName(std::string_view name) {
  return !name.empty() && name != "." && name != ".." &&
         name.find_first_of(std::string_view("/\\\0", 3)) == std::string_view::npos;
}

// "a.jpg" -> "a (2).jpg".
std::string WithSuffix(const std::string& name, int n) {
  const std::size_t dot = name.rfind('.');
  const std::string suffix = " (" + std::to_string(n) + ")";
  if (dot == std::string::npos || dot == 0) return name + suffix;
  return name.substr(0, dot) + suffix + name.substr(dot);
}

// The temporary file of an atomic write in core/io ("<name>.tmp-<pid>-<random>", renamed to
// <name> once complete). One in output/ means a run died in the middle of writing a deliverable.
bool IsInterruptedWrite(std::string_view name) {
  const std::size_t at = name.rfind(".tmp-");
  if (at == std::string_view::npos || at == 0) return false;
  const std::string_view rest = name.substr(at + 5);  // "<pid>-<random>"
  const std::size_t dash = rest.find('-');
  if (dash == std::string_view::npos || dash == 0 || dash + 1 == rest.size()) return false;
  const auto digits = [](std::string_view text) {
    return std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  return digits(rest.substr(0, dash)) && digits(rest.substr(dash + 1));
}

// Removes the half-written deliverables a killed run left in `output_dir`: packaging packs
// every file of the folder, and the API lists them, so they would be delivered as results.
// Returns how many were removed.
int RemoveInterruptedWrites(const fs::path& output_dir) {
  std::vector<fs::path> leftovers;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(output_dir, ec), end; !ec && it != end;
       it.increment(ec)) {
    if (!it->is_symlink(ec) && it->is_regular_file(ec) &&
        IsInterruptedWrite(it->path().filename().string())) {
      leftovers.push_back(it->path());
    }
  }
  int removed = 0;
  for (const fs::path& path : leftovers) {
    if (fs::remove(path, ec)) ++removed;
  }
  return removed;
}

// A heartbeat thread: calls `beat` every `interval` until destroyed.
class HeartbeatThread {
 public:
  HeartbeatThread(std::chrono::milliseconds interval, std::function<void()> beat)
      : interval_(interval), beat_(std::move(beat)), thread_([this] { Loop(); }) {}
  HeartbeatThread(const HeartbeatThread&) = delete;
  HeartbeatThread& operator=(const HeartbeatThread&) = delete;
  ~HeartbeatThread() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }

 private:
  void Loop() {
    std::unique_lock lock(mutex_);
    while (!wake_.wait_for(lock, interval_, [this] { return done_; })) {
      lock.unlock();
      try {
        beat_();
      } catch (const std::exception& e) {
        LOG_WARNING << "heartbeat failed: " << e.what();
      }
      lock.lock();
    }
  }

  const std::chrono::milliseconds interval_;
  const std::function<void()> beat_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;  // Last: starts after the members it uses.
};

}  // namespace

std::string_view JobRunOutcomeName(JobRunOutcome outcome) {
  switch (outcome) {
    case JobRunOutcome::kSucceeded:
      return "succeeded";
    case JobRunOutcome::kFailed:
      return "failed";
    case JobRunOutcome::kCanceled:
      return "canceled";
    case JobRunOutcome::kReleased:
      return "released";
    case JobRunOutcome::kLeaseLost:
      return "lease lost";
    case JobRunOutcome::kStoreError:
      return "store error";
  }
  return "unknown";
}

bool JobRunnerOptions::Check(std::string* error) const {
  if (worker_id.empty()) {
    *error = "worker_id must not be empty";
    return false;
  }
  if (lease.count() < 100) {
    *error = "lease must be at least 100 ms";
    return false;
  }
  if (heartbeat_interval.count() < 0 || heartbeat_interval >= lease) {
    *error = "heartbeat_interval must be in [0, lease)";
    return false;
  }
  if (cancel_check_interval.count() < 0) {
    *error = "cancel_check_interval must be >= 0";
    return false;
  }
  if (default_num_threads < 0 || default_num_threads > 256) {
    *error = "default_num_threads must be in [0, 256]";
    return false;
  }
  return sink.Check(error);
}

Result<std::vector<JobPhoto>> PhotosFromRecords(const std::vector<JobImageRecord>& records,
                                                const fs::path& input_dir) {
  std::vector<const JobImageRecord*> accepted;
  for (const JobImageRecord& record : records) {
    if (record.status == ImageStatus::kAccepted) accepted.push_back(&record);
  }
  std::stable_sort(
      accepted.begin(), accepted.end(),
      [](const JobImageRecord* a, const JobImageRecord* b) { return a->index < b->index; });
  if (accepted.empty()) return Status::InvalidArgument("the job has no accepted photo");
  std::vector<JobPhoto> photos;
  std::set<std::string> names;
  for (const JobImageRecord* record : accepted) {
    if (!IsPlainFileName(record->stored_name)) {
      return Status::InvalidArgument("photo " + std::to_string(record->index) +
                                     " has an unsafe stored name " + Quote(record->stored_name));
    }
    std::string name = BaseName(record->original_name);
    if (name.empty()) name = record->stored_name;
    std::string unique = name;
    for (int n = 2; names.count(unique) > 0; ++n) unique = WithSuffix(name, n);
    names.insert(unique);
    photos.push_back({input_dir / record->stored_name, unique});
  }
  return photos;
}

nlohmann::json CountsFromStageSummary(std::string_view stage, const nlohmann::json& summary) {
  if (!summary.is_object()) return nullptr;
  // {stage, summary key, count name}; "" matches any stage. Stages that land later add rows.
  struct Mapping {
    std::string_view stage, key, count;
  };
  static constexpr Mapping kMappings[] = {
      {"ingest", "accepted", "images"},
      {"ingest", "rejected", "rejected_images"},
      {"features", "features", "features"},
      {"pairs", "pairs", "candidate_pairs"},
      {"matching", "pairs", "matched_pairs"},
      {"matching", "inlier_matches", "inlier_matches"},
      {"package", "files", "result_files"},
      {"", "registered", "registered"},
      {"", "points", "points"},
      {"", "faces", "faces"},
      {"", "models", "models"},
  };
  nlohmann::json counts = nlohmann::json::object();
  for (const Mapping& m : kMappings) {
    if (!m.stage.empty() && m.stage != stage) continue;
    const auto it = summary.find(m.key);
    if (it != summary.end() && it->is_number()) counts[std::string(m.count)] = *it;
  }
  if (counts.empty()) return nullptr;
  return counts;
}

JobRunner::JobRunner(JobStore& store, JobRunnerOptions options)
    : store_(store), options_(std::move(options)), layout_(options_.data_dir) {
  std::string error;
  THROW_CHECK(options_.Check(&error)) << error;
}

void JobRunner::RequestStop() {
  stop_requested_ = true;
  std::lock_guard lock(running_mutex_);
  running_cancel_.RequestCancel();
}

Status JobRunner::ReleaseRunningJobNow() {
  std::string id;
  {
    std::lock_guard lock(running_mutex_);
    id = running_job_id_;
  }
  if (id.empty()) return Status::NotFound("no job is running");
  Result<JobState> state = store_.ReleaseJob(id, options_.worker_id);
  if (!state.ok()) return state.status();
  return Status::Ok();
}

std::string JobRunner::running_job_id() const {
  std::lock_guard lock(running_mutex_);
  return running_job_id_;
}

JobRunReport JobRunner::Run(const Job& job) {
  const Timer timer;
  JobRunReport report;
  const std::string& worker = options_.worker_id;
  CancelToken cancel;
  {
    std::lock_guard lock(running_mutex_);
    running_job_id_ = job.id;
    running_cancel_ = cancel;
  }
  // RequestStop may have come between the claim and here.
  if (stop_requested_) cancel.RequestCancel();

  ProgressSink sink(store_, job.id, worker, options_.sink);
  std::atomic<bool> lease_lost{false};
  std::atomic<bool> cancel_requested{false};
  sink.SetOnLeaseLost([&] {
    lease_lost = true;
    cancel.RequestCancel();
  });

  // One heartbeat: renews the lease and learns about a cancel request or a lost job.
  std::mutex beat_mutex;
  bool finishing = false;  // Guarded by beat_mutex: no beats once the final write begins.
  auto beat = [&] {
    std::lock_guard lock(beat_mutex);
    if (finishing || lease_lost) return;
    const Result<HeartbeatReply> reply = store_.Heartbeat(job.id, worker, options_.lease);
    if (!reply.ok()) {
      // A busy database: the next beat tries again, well within the lease.
      LOG_WARNING << "job " << job.id << ": heartbeat failed: " << reply.status();
      return;
    }
    if (!reply->owned) {
      if (!lease_lost.exchange(true)) {
        LOG_WARNING << "job " << job.id << ": the lease was lost; stopping without finishing";
      }
      cancel.RequestCancel();
    } else if (reply->cancel_requested) {
      if (!cancel_requested.exchange(true)) {
        LOG_INFO << "job " << job.id << ": cancel requested; stopping";
      }
      cancel.RequestCancel();
    }
  };

  auto moment = [this](const std::string& name) {
    if (options_.on_moment) options_.on_moment(name);
  };

  // What the job's run leaves behind for the final decision.
  std::string current_stage;
  nlohmann::json counts = nlohmann::json::object();

  auto finish = [&](JobRunOutcome outcome, std::string stage, std::string message) {
    report.outcome = outcome;
    report.stage = std::move(stage);
    report.message = std::move(message);
    report.seconds = timer.ElapsedSeconds();
    std::lock_guard lock(running_mutex_);
    running_job_id_.clear();
    running_cancel_ = CancelToken();
    return report;
  };
  // Writes a final state through `write` and maps the store's answer to the outcome.
  auto finish_with = [&](JobRunOutcome outcome, std::string stage, std::string message,
                         auto write) {
    {
      // A beat after the final write would find the job not ours and cry "lease lost".
      std::lock_guard lock(beat_mutex);
      finishing = true;
    }
    sink.Close();
    if (lease_lost) {
      return finish(JobRunOutcome::kLeaseLost, std::move(stage), "the lease was lost");
    }
    const auto answer = RetryStoreWrite(write);
    const Status& status = StatusOf(answer);
    if (status.ok()) return finish(outcome, std::move(stage), std::move(message));
    if (status.code() == StatusCode::kFailedPrecondition ||
        status.code() == StatusCode::kNotFound) {
      LOG_WARNING << "job " << job.id << ": not ours any more: " << status;
      return finish(JobRunOutcome::kLeaseLost, std::move(stage), status.message());
    }
    LOG_ERROR << "job " << job.id << ": cannot record the end of the job (" << status
              << "); its lease will expire and it will run again";
    return finish(JobRunOutcome::kStoreError, std::move(stage), status.message());
  };
  auto fail = [&](std::string stage, std::string message) {
    return finish_with(JobRunOutcome::kFailed, stage, message,
                       [&] { return store_.FinishFailed(job.id, worker, message, stage); });
  };

  try {
    // Every log line of the job goes to the worker's log and, rate-limited, to the job's events.
    auto previous_sink = std::make_shared<LogSink>(SetLogSink({}));
    SetLogSink(*previous_sink);  // Only to learn it; ScopedLogSink replaces it next.
    const std::string prefix = "[job " + job.id.substr(0, 8) + "] ";
    ScopedLogSink log_sink([previous_sink, prefix, &sink](LogLevel level, std::string_view line) {
      const std::string text = prefix + std::string(line);
      if (*previous_sink) {
        (*previous_sink)(level, text);
      } else {
        WriteStderrLine(level, text);
      }
      sink.AddLogLine(level, line);
    });

    const std::chrono::milliseconds interval =
        options_.heartbeat_interval.count() > 0 ? options_.heartbeat_interval : options_.lease / 3;
    cancel.SetProbe(
        [&] {
          beat();
          return lease_lost.load() || cancel_requested.load() || stop_requested_.load();
        },
        options_.cancel_check_interval);
    // Clears the probe (it refers to this frame) when Run leaves, whatever the path.
    struct ProbeReset {
      const CancelToken& token;
      ~ProbeReset() { token.SetProbe({}); }
    } probe_reset{cancel};
    HeartbeatThread heartbeat(interval, [&] {
      beat();
      sink.Flush();
    });

    LOG_INFO << "running job " << job.id << " (" << job.image_count << " photos, run "
             << job.attempts + 1 << " of at most " << job.max_attempts << ")";

    // The options the server validated; parsed again here because the worker may be newer or
    // older than the server that accepted them.
    Result<PipelineOptions> options = ParsePipelineOptions(job.options);
    if (!options.ok()) return fail("", "invalid options: " + options.status().message());
    PipelineJob pipeline_job;
    pipeline_job.options = *options;
    if (options_.default_num_threads > 0 && !job.options.contains("num_threads")) {
      pipeline_job.options.num_threads = options_.default_num_threads;
    }

    const Result<std::vector<JobImageRecord>> images = store_.ListImages(job.id);
    if (!images.ok()) {
      if (images.status().code() == StatusCode::kNotFound) {
        return finish(JobRunOutcome::kLeaseLost, "", "the job was deleted");
      }
      return fail("", "cannot read the job's photos: " + images.status().message());
    }
    Result<std::vector<JobPhoto>> photos = PhotosFromRecords(*images, layout_.InputDir(job.id));
    if (!photos.ok()) return fail("", photos.status().message());
    pipeline_job.photos = std::move(photos).value();
    pipeline_job.work_dir = layout_.WorkDir(job.id);
    pipeline_job.output_dir = layout_.OutputDir(job.id);
    pipeline_job.archive_path = layout_.ResultZip(job.id);
    for (const fs::path& dir : {pipeline_job.work_dir, pipeline_job.output_dir}) {
      std::error_code ec;
      fs::create_directories(dir, ec);
      if (ec) return fail("", "cannot create " + dir.string() + ": " + ec.message());
    }
    if (const int removed = RemoveInterruptedWrites(pipeline_job.output_dir); removed > 0) {
      LOG_WARNING << "removed " << removed
                  << " half-written file(s) of an interrupted run from output/";
    }

    const std::set<std::string> finished_in_store(job.finished_stages.begin(),
                                                  job.finished_stages.end());
    Clock::time_point stage_started = Clock::now();

    PipelineDriverCallbacks callbacks;
    callbacks.on_plan = [&](const std::vector<StagePlan>& plan) {
      // The store and the work folder must agree on what is finished. A stage the store lists
      // without a complete marker on disk runs again (its output cannot be trusted); a marker
      // the store does not know yet is recorded when the runner resumes the stage.
      for (const StagePlan& stage : plan) {
        if (finished_in_store.count(stage.name) > 0 && !stage.finished_on_disk) {
          sink.AddEvent({stage.name, LogLevel::kWarning,
                         "stage " + Quote(stage.name) +
                             " was recorded as finished but its output in work/" + stage.name +
                             " is missing or incomplete; running it again",
                         std::nullopt});
        }
      }
    };
    callbacks.on_stage_start = [&](const StagePlan& stage, double overall) {
      current_stage = stage.name;
      stage_started = Clock::now();
      if (stage.finished_on_disk) return;  // Reported when the runner skips it.
      sink.AddEvent({stage.name, LogLevel::kInfo,
                     "stage " + Quote(stage.name) + " started: " + stage.title, overall});
      sink.StageStarted(stage.name, overall,
                        {{"progress", 0.0}, {"title", stage.title}, {"status", "running"}});
      moment("stage-started:" + stage.name);
    };
    callbacks.on_progress = [&](const StagePlan& stage, double fraction, std::size_t done,
                                std::size_t total, const std::string& message, double overall) {
      const double seconds = std::chrono::duration<double>(Clock::now() - stage_started).count();
      sink.StageProgress(stage.name, overall,
                         {{"progress", fraction},
                          {"done", done},
                          {"total", total},
                          {"message", message},
                          {"seconds", seconds},
                          {"memory_bytes", CurrentMemoryBytes()}});
    };
    callbacks.on_stage_end = [&](const StageOutcome& outcome, double overall) {
      nlohmann::json stage_counts =
          outcome.success ? CountsFromStageSummary(outcome.name, outcome.summary) : nullptr;
      if (stage_counts.is_object()) counts.merge_patch(stage_counts);
      nlohmann::json patch = {{"status", outcome.resumed ? "resumed" : outcome.status},
                              {"seconds", outcome.seconds},
                              {"peak_memory_bytes", outcome.peak_memory_bytes}};
      if (outcome.success) {
        patch["progress"] = 1.0;
        patch["summary"] = outcome.summary;
      }
      if (!outcome.message.empty()) patch["message"] = outcome.message;

      std::string text;
      LogLevel level = LogLevel::kInfo;
      if (outcome.resumed) {
        report.resumed_stages.push_back(outcome.name);
        text = "stage " + Quote(outcome.name) + " finished in an earlier run (" +
               FormatSeconds(outcome.seconds) + "); skipped";
      } else {
        report.run_stages.push_back(outcome.name);
        text = "stage " + Quote(outcome.name) + " " + outcome.status + " after " +
               FormatSeconds(outcome.seconds) + ", peak memory " +
               FormatMiB(outcome.peak_memory_bytes);
        if (outcome.success && !outcome.summary.empty()) text += ": " + outcome.summary.dump();
        if (!outcome.success) {
          level = outcome.status == "canceled" ? LogLevel::kInfo : LogLevel::kError;
          text += ": " + outcome.message;
        }
      }
      if (outcome.success && !outcome.resumed) moment("stage-done:" + outcome.name);
      sink.AddEvent({outcome.name, level, text, overall});
      sink.StageEnded(outcome.name, overall, std::move(patch), stage_counts);
      // Resumable stages whose output is complete become resumable for later runs in the
      // store too. Packaging (not resumable) runs every time and is not listed.
      if (outcome.success && outcome.resumable &&
          (!outcome.resumed || finished_in_store.count(outcome.name) == 0)) {
        const Status marked = sink.MarkStageFinished(outcome.name, outcome.seconds);
        if (!marked.ok() && !sink.lease_lost()) {
          // Not fatal: the marker on disk still lets the next run resume; the store catches
          // up then (the resumed-stage case above).
          LOG_WARNING << "cannot record stage " << outcome.name << " as finished: " << marked;
        }
      }
    };

    const PipelineOutcome outcome =
        RunJobPipeline(pipeline_job, options_.make_stages, cancel, callbacks);
    // Final heartbeat: the lease must still be ours (and long enough) for the last writes.
    beat();

    switch (outcome.status) {
      case PipelineOutcomeStatus::kSuccess: {
        // The packaging stage reports the archive it wrote; check it is the file on disk.
        const StageOutcome* packaging = nullptr;
        for (const StageOutcome& stage : outcome.stages) {
          if (stage.summary.contains("archive_sha256") && stage.summary.contains("archive_bytes"))
            packaging = &stage;
        }
        if (packaging == nullptr) {
          return fail(outcome.stages.empty() ? "" : outcome.stages.back().name,
                      "the pipeline finished without writing result.zip");
        }
        JobOutput output;
        output.result_bytes = packaging->summary["archive_bytes"].get<std::int64_t>();
        output.result_sha256 = packaging->summary["archive_sha256"].get<std::string>();
        output.counts = counts;
        std::error_code ec;
        const std::uintmax_t size = fs::file_size(pipeline_job.archive_path, ec);
        if (ec || static_cast<std::int64_t>(size) != output.result_bytes) {
          return fail(packaging->name,
                      "result.zip is missing or does not have the size the "
                      "packaging stage reported");
        }
        LOG_INFO << "job " << job.id << " succeeded in " << FormatSeconds(outcome.seconds)
                 << ": result.zip " << output.result_bytes << " bytes";
        moment("before-finish");
        return finish_with(JobRunOutcome::kSucceeded, "", "",
                           [&] { return store_.FinishSucceeded(job.id, worker, output); });
      }
      case PipelineOutcomeStatus::kCanceled:
      case PipelineOutcomeStatus::kFailed: {
        if (lease_lost) return finish(JobRunOutcome::kLeaseLost, outcome.failed_stage, "");
        const bool canceled = outcome.status == PipelineOutcomeStatus::kCanceled;
        if (cancel_requested) {
          // A client's cancel wins over a stop: it is what they asked for.
          LOG_INFO << "job " << job.id << " canceled in stage " << outcome.failed_stage;
          return finish_with(JobRunOutcome::kCanceled, outcome.failed_stage, outcome.message,
                             [&] { return store_.FinishCanceled(job.id, worker); });
        }
        if (stop_requested_) {
          // The worker is stopping. Even a failure may be the stop's doing (a stage that
          // reports cancellation as an error); the next worker finds out.
          LOG_INFO << "job " << job.id << ": worker stopping; giving the job back";
          return finish_with(JobRunOutcome::kReleased, outcome.failed_stage, outcome.message,
                             [&] { return store_.ReleaseJob(job.id, worker); });
        }
        if (canceled) {
          return fail(outcome.failed_stage,
                      "stage " + outcome.failed_stage +
                          " stopped without a cancel request: " + outcome.message);
        }
        LOG_WARNING << "job " << job.id << " failed in stage " << outcome.failed_stage << ": "
                    << outcome.message;
        return fail(outcome.failed_stage, outcome.message.empty() ? "failed" : outcome.message);
      }
    }
    return fail(current_stage, "unknown pipeline outcome");
  } catch (const std::exception& e) {
    return fail(current_stage, std::string("internal error in the worker: ") + e.what());
  } catch (...) {
    return fail(current_stage, "internal error in the worker: unknown exception");
  }
}

}  // namespace reconduit
