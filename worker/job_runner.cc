#include "worker/job_runner.h"

#include "core/pipeline/runner.h"
#include "core/util/default_log_sink.h"
#include "core/util/logging.h"
#include "core/util/timer.h"
#include "worker/memory_budget.h"

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <optional>
#include <set>
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

// While a job runs: every log line goes to the previous sink (the default one: the process's
// one line layout) with the job's id at the head of the message, and, rate-limited, to the
// job's events. Restores the previous sink when destroyed.
class JobLogSink {
 public:
  JobLogSink(const std::string& job_id, ProgressSink& events) {
    auto previous = std::make_shared<LogSink>(SetLogSink({}));
    SetLogSink(*previous);  // Only to learn it; replaced next.
    previous_ = *previous;
    const std::string prefix = "[job " + job_id.substr(0, 8) + "] ";
    SetLogSink([previous, prefix, &events](LogLevel level, std::string_view line) {
      const std::string text = prefix + std::string(line);
      if (*previous) {
        (*previous)(level, text);
      } else {
        DefaultLogSink(level, text);
      }
      events.AddLogLine(level, line);
    });
  }
  JobLogSink(const JobLogSink&) = delete;
  JobLogSink& operator=(const JobLogSink&) = delete;
  ~JobLogSink() { SetLogSink(std::move(previous_)); }

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

// A stage's failure message said in the words an operator acts on when the cause was a full
// disk, whatever wrote the file: core/io's writes begin "out of disk space", libzip, OpenCV and
// streams name the system's error. Other messages are returned unchanged.
std::string ExplainDiskFull(const std::string& message) {
  const bool full = message.find("out of disk space") != std::string::npos ||
                    message.find(std::strerror(ENOSPC)) != std::string::npos ||
                    message.find(std::strerror(EDQUOT)) != std::string::npos;
  if (!full) return message;
  std::string explained =
      message.starts_with("out of disk space") ? message : "out of disk space: " + message;
  return explained +
         ". Free space in the worker's data folder, then restart the job (POST "
         "/api/v1/jobs/{id}/restart): the stages it finished are kept.";
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
  if (memory_budget_bytes < 0) {
    *error = "memory_budget_bytes must be >= 0";
    return false;
  }
  if (memory_check_interval.count() <= 0) {
    *error = "memory_check_interval must be > 0";
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

Result<std::vector<InputImage>> PhotosFromRecords(const std::vector<JobImageRecord>& records,
                                                  const fs::path& input_dir) {
  std::vector<const JobImageRecord*> accepted;
  for (const JobImageRecord& record : records) {
    if (record.photo.accepted) accepted.push_back(&record);
  }
  std::stable_sort(
      accepted.begin(), accepted.end(),
      [](const JobImageRecord* a, const JobImageRecord* b) { return a->index < b->index; });
  if (accepted.empty()) return Status::InvalidArgument("the job has no accepted photo");
  std::vector<InputImage> photos;
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

int JobThreads(int requested, int worker_limit) {
  const int limit = worker_limit > 0
                        ? worker_limit
                        : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (requested > limit) {
    LOG_INFO << "the job asks for " << requested << " threads; the worker allows " << limit;
  }
  return requested <= 0 ? limit : std::min(requested, limit);
}

JobCounts CountsOfStage(const StageRecord& record) {
  JobCounts counts;
  if (record.status != StageStatus::kSuccess) return counts;
  // An integer of the summary, when there.
  const auto take = [&](const char* key, std::optional<std::int64_t>& count) {
    const auto it = record.summary.find(key);
    if (record.summary.is_object() && it != record.summary.end() && it->is_number()) {
      count = it->get<std::int64_t>();
    }
  };
  const std::string& stage = record.name;
  if (stage == "ingest") {
    take("accepted", counts.images);
    take("rejected", counts.rejected_images);
  } else if (stage == "features") {
    take("features", counts.features);
  } else if (stage == "pairs") {
    take("pairs", counts.candidate_pairs);
  } else if (stage == "matching") {
    take("pairs", counts.matched_pairs);
    take("inlier_matches", counts.inlier_matches);
  }
  // Figures of the reconstruction, from whichever stage reports them.
  take("registered", counts.registered);
  take("points", counts.points);
  take("faces", counts.faces);
  take("models", counts.models);
  if (record.package) {
    counts.result_files = static_cast<std::int64_t>(record.package->archive.files.size());
  }
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

namespace {

// One run of one claimed job: the steps of JobRunner::Run and the state they share. The steps,
// in order: keep the lease (a heartbeat thread and the cancel token's probe), prepare the
// inputs, run the pipeline with callbacks that mirror it into the store, and finish the job
// in the store according to how the pipeline ended and why.
class JobRun {
 public:
  JobRun(JobStore& store,
         const JobRunnerOptions& options,
         const DataLayout& layout,
         const std::atomic<bool>& stop_requested,
         const Job& job,
         CancelToken cancel)
      : store_(store),
        options_(options),
        layout_(layout),
        stop_requested_(stop_requested),
        job_(job),
        cancel_(std::move(cancel)),
        sink_(store, job.id, options.worker_id, options.sink),
        finished_in_store_(job.finished_stages.begin(), job.finished_stages.end()) {
    sink_.SetOnLeaseLost([this] {
      lease_lost_ = true;
      cancel_.RequestCancel();
    });
  }

  // Never throws: every exception becomes a failed job.
  JobRunReport Execute() {
    try {
      return KeepLeaseAndRun();
    } catch (const std::exception& e) {
      return Fail(current_stage_, std::string("internal error in the worker: ") + e.what());
    } catch (...) {
      return Fail(current_stage_, "internal error in the worker: unknown exception");
    }
  }

 private:
  // The lease and the log sink last as long as the run; the rest is RunPipelineAndFinish.
  JobRunReport KeepLeaseAndRun() {
    JobLogSink log_sink(job_.id, sink_);
    cancel_.SetProbe([this] { return BeatAndCheckStop(); }, options_.cancel_check_interval);
    // Clears the probe (it refers to this object) when the run ends, whatever the path.
    struct ProbeReset {
      const CancelToken& token;
      ~ProbeReset() { token.SetProbe({}); }
    } probe_reset{cancel_};
    const std::chrono::milliseconds interval =
        options_.heartbeat_interval.count() > 0 ? options_.heartbeat_interval : options_.lease / 3;
    HeartbeatThread heartbeat(interval, [this] {
      Beat();
      sink_.Flush();
    });
    MemoryWatch memory(options_.memory_budget_bytes, options_.memory_check_interval,
                       [this](std::int64_t resident) {
                         over_budget_bytes_ = resident;
                         LOG_WARNING << "job " << job_.id << ": " << FormatMemory(resident)
                                     << " resident, over the budget of "
                                     << FormatMemory(options_.memory_budget_bytes) << "; stopping";
                         cancel_.RequestCancel();
                       });
    LOG_INFO << "running job " << job_.id << " (" << job_.image_count << " photos, run "
             << job_.attempts + 1 << " of at most " << job_.max_attempts << ")";
    return RunPipelineAndFinish();
  }

  JobRunReport RunPipelineAndFinish() {
    Workspace workspace;
    PipelineOptions options;
    if (std::optional<JobRunReport> ended = PrepareInputs(&workspace, &options)) return *ended;
    const PipelineResult result =
        RunJobPipeline(workspace, options, options_.make_stages, cancel_, StoreMirror());
    // Final heartbeat: the lease must still be ours (and long enough) for the last writes.
    Beat();
    if (result.status != StageStatus::kSuccess) return FinishUnsuccessful(result);
    JobRunReport report = FinishSucceeded(result);
    // Only once the store has the job as succeeded: until then a new worker may resume it.
    if (report.outcome == JobRunOutcome::kSucceeded && !options.keep_work_files) {
      RemoveWorkFiles(workspace.work_dir);
    }
    return report;
  }

  // The intermediate files (features, matches, depth maps, ...) of a succeeded job: they can be
  // ten times the size of result.zip. A failure to remove them is logged, not an error of the
  // job.
  void RemoveWorkFiles(const fs::path& work_dir) {
    std::error_code ec;
    const std::uintmax_t removed = fs::remove_all(work_dir, ec);
    if (ec) {
      LOG_WARNING << "job " << job_.id << ": cannot remove its work files " << work_dir << ": "
                  << ec.message();
    } else {
      LOG_INFO << "job " << job_.id << ": removed " << removed
               << " work files (the option keep_work_files keeps them)";
    }
  }

  // ---- Heartbeat ----

  // One heartbeat: renews the lease and learns about a cancel request or a lost job.
  void Beat() {
    std::lock_guard lock(beat_mutex_);
    if (finishing_ || lease_lost_) return;
    const Result<HeartbeatReply> reply =
        store_.Heartbeat(job_.id, options_.worker_id, options_.lease);
    if (!reply.ok()) {
      // A busy database: the next beat tries again, well within the lease.
      LOG_WARNING << "job " << job_.id << ": heartbeat failed: " << reply.status();
      return;
    }
    if (!reply->owned) {
      if (!lease_lost_.exchange(true)) {
        LOG_WARNING << "job " << job_.id << ": the lease was lost; stopping without finishing";
      }
      cancel_.RequestCancel();
    } else if (reply->cancel_requested) {
      if (!cancel_requested_.exchange(true)) {
        LOG_INFO << "job " << job_.id << ": cancel requested; stopping";
      }
      cancel_.RequestCancel();
    }
  }

  // The cancel token's probe: a beat, then whether the stage should stop.
  bool BeatAndCheckStop() {
    Beat();
    return lease_lost_.load() || cancel_requested_.load() || stop_requested_.load();
  }

  // ---- Inputs ----

  // The job's options and workspace: options parsed again (the worker may be newer or older
  // than the server that validated them), accepted photos, the job's folders, and output/
  // without the half-written files of an interrupted run. Returns the finished report when
  // the job cannot run.
  std::optional<JobRunReport> PrepareInputs(Workspace* workspace, PipelineOptions* options) {
    Result<PipelineOptions> parsed = ParsePipelineOptions(job_.options);
    if (!parsed.ok()) return Fail("", "invalid options: " + parsed.status().message());
    *options = *parsed;
    options->num_threads = JobThreads(options->num_threads, options_.default_num_threads);

    const Result<std::vector<JobImageRecord>> images = store_.ListImages(job_.id);
    if (!images.ok()) {
      if (images.status().code() == StatusCode::kNotFound) {
        return Finish(JobRunOutcome::kLeaseLost, "", "the job was deleted");
      }
      return Fail("", "cannot read the job's photos: " + images.status().message());
    }
    Result<std::vector<InputImage>> photos = PhotosFromRecords(*images, layout_.InputDir(job_.id));
    if (!photos.ok()) return Fail("", photos.status().message());
    workspace->images = std::move(photos).value();
    workspace->work_dir = layout_.WorkDir(job_.id);
    workspace->output_dir = layout_.OutputDir(job_.id);
    workspace->archive_path = layout_.ResultZip(job_.id);
    for (const fs::path& dir : {workspace->work_dir, workspace->output_dir}) {
      std::error_code ec;
      fs::create_directories(dir, ec);
      if (ec) return Fail("", "cannot create " + dir.string() + ": " + ec.message());
    }
    if (const int removed = RemoveInterruptedWrites(workspace->output_dir); removed > 0) {
      LOG_WARNING << "removed " << removed
                  << " half-written file(s) of an interrupted run from output/";
    }
    return std::nullopt;
  }

  // ---- The pipeline mirrored into the store ----

  PipelineCallbacks StoreMirror() {
    PipelineCallbacks callbacks;
    callbacks.on_plan = [this](const std::vector<StagePlan>& plan) { OnPlan(plan); };
    callbacks.on_stage_start = [this](const Stage& stage, double overall) {
      OnStageStart(stage, overall);
    };
    callbacks.on_progress = [this](const Stage& stage, const ProgressUpdate& update,
                                   double overall) { OnProgress(stage, update, overall); };
    callbacks.on_stage_end = [this](const Stage&, const StageRecord& record, double overall) {
      OnStageEnd(record, overall);
    };
    return callbacks;
  }

  // The store and the work folder must agree on what is finished. A stage the store lists
  // without a complete marker on disk runs again (its output cannot be trusted); a marker the
  // store does not know yet is recorded when the runner resumes the stage (OnStageEnd).
  void OnPlan(const std::vector<StagePlan>& plan) {
    for (const StagePlan& stage : plan) {
      if (stage.finished_on_disk) resumed_from_disk_.insert(stage.name);
      if (finished_in_store_.count(stage.name) > 0 && !stage.finished_on_disk) {
        sink_.AddEvent({stage.name, LogLevel::kWarning,
                        "stage " + Quote(stage.name) +
                            " was recorded as finished but its output in work/" + stage.name +
                            " is missing or incomplete; running it again",
                        std::nullopt});
      }
    }
  }

  void OnStageStart(const Stage& stage, double overall) {
    const std::string name(stage.Name());
    const std::string title(stage.Title());
    current_stage_ = name;
    stage_started_ = Clock::now();
    if (resumed_from_disk_.count(name) > 0) return;  // Reported when the runner skips it.
    sink_.AddEvent({name, LogLevel::kInfo, "stage " + Quote(name) + " started: " + title, overall});
    sink_.StageStarted(name, overall, {{"progress", 0.0}, {"title", title}, {"status", "running"}});
    Moment("stage-started:" + name);
  }

  void OnProgress(const Stage& stage, const ProgressUpdate& update, double overall) {
    const double seconds = std::chrono::duration<double>(Clock::now() - stage_started_).count();
    sink_.StageProgress(std::string(stage.Name()), overall,
                        {{"progress", update.fraction},
                         {"done", update.done},
                         {"total", update.total},
                         {"message", update.message},
                         {"seconds", seconds},
                         {"memory_bytes", CurrentMemoryBytes()}});
  }

  // The stage's final figures, counts and event; and, for a resumable stage whose output is
  // complete, MarkStageFinished (also for a stage resumed from disk that the store had not
  // recorded, e.g. after a crash between the marker and the store write).
  void OnStageEnd(const StageRecord& record, double overall) {
    const bool success = record.status == StageStatus::kSuccess;
    const JobCounts stage_counts = CountsOfStage(record);
    counts_.Merge(stage_counts);
    (record.resumed ? report_.resumed_stages : report_.run_stages).push_back(record.name);
    if (success && !record.resumed) Moment("stage-done:" + record.name);
    sink_.AddEvent(StageEndEvent(record, overall));
    sink_.StageEnded(record.name, overall, StageEndPatch(record), stage_counts);
    // Packaging (not resumable) runs every time and is not listed.
    if (success && record.resumable &&
        (!record.resumed || finished_in_store_.count(record.name) == 0)) {
      const Status marked = sink_.MarkStageFinished(record.name, record.seconds);
      if (!marked.ok() && !sink_.lease_lost()) {
        // Not fatal: the marker on disk still lets the next run resume; the store catches
        // up then (the resumed-stage case above).
        LOG_WARNING << "cannot record stage " << record.name << " as finished: " << marked;
      }
    }
  }

  // The patch of the stage's entry in Job::stage_progress.
  static nlohmann::json StageEndPatch(const StageRecord& record) {
    const bool success = record.status == StageStatus::kSuccess;
    nlohmann::json patch = {
        {"status",
         record.resumed ? std::string("resumed") : std::string(StageStatusName(record.status))},
        {"seconds", record.seconds},
        {"peak_memory_bytes", record.peak_memory_bytes},
        {"stage_peak_memory_bytes", record.stage_peak_memory_bytes},
        {"stage_peak_memory_own", record.stage_peak_memory_own}};
    if (success) {
      patch["progress"] = 1.0;
      patch["summary"] = record.summary;
    }
    if (!record.message.empty()) patch["message"] = record.message;
    return patch;
  }

  // `summary` with every list, at any depth, replaced by "<n> entries".
  static nlohmann::json BriefSummary(nlohmann::json summary) {
    for (auto& [key, value] : summary.items()) {
      if (value.is_array()) {
        value = std::to_string(value.size()) + " entries";
      } else if (value.is_object()) {
        value = BriefSummary(std::move(value));
      }
    }
    return summary;
  }

  // The job event for the end of a stage: skipped, or how it ended with time and memory.
  static NewEvent StageEndEvent(const StageRecord& record, double overall) {
    const bool success = record.status == StageStatus::kSuccess;
    if (record.resumed) {
      return {record.name, LogLevel::kInfo,
              "stage " + Quote(record.name) + " finished in an earlier run (" +
                  FormatSeconds(record.seconds) + "); skipped",
              overall};
    }
    std::string text = "stage " + Quote(record.name) + " " +
                       std::string(StageStatusName(record.status)) + " after " +
                       FormatSeconds(record.seconds) + ", peak memory " +
                       FormatMiB(record.peak_memory_bytes);
    if (record.stage_peak_memory_own) {
      text += " (the stage's own " + FormatMiB(record.stage_peak_memory_bytes) + ")";
    }
    LogLevel level = LogLevel::kInfo;
    if (success && !record.summary.empty()) {
      // Lists (the dense stage's per-map figures, the sparse stage's photos left out) are in
      // the job's stage records and the report; the event line says how long they are.
      text += ": " + BriefSummary(record.summary).dump();
    }
    if (!success) {
      level = record.status == StageStatus::kCanceled ? LogLevel::kInfo : LogLevel::kError;
      text += ": " + record.message;
    }
    return {record.name, level, text, overall};
  }

  // ---- Finishing ----

  // Succeeded with the archive the packaging stage reports, once checked against the file.
  JobRunReport FinishSucceeded(const PipelineResult& result) {
    const StageRecord* packaging = nullptr;
    for (const StageRecord& stage : result.stages) {
      if (stage.package) packaging = &stage;
    }
    if (packaging == nullptr) {
      return Fail(result.stages.empty() ? "" : result.stages.back().name,
                  "the pipeline finished without writing result.zip");
    }
    const PackageResult& package = *packaging->package;
    JobOutput output;
    output.result_bytes = package.archive.archive_bytes;
    output.result_sha256 = package.archive.archive_sha256;
    output.counts = counts_;
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(package.archive_path, ec);
    if (ec || static_cast<std::int64_t>(size) != output.result_bytes) {
      return Fail(packaging->name,
                  "result.zip is missing or does not have the size the packaging stage reported");
    }
    LOG_INFO << "job " << job_.id << " succeeded in " << FormatSeconds(result.seconds)
             << ": result.zip " << output.result_bytes << " bytes";
    Moment("before-finish");
    return FinishWith(JobRunOutcome::kSucceeded, "", "",
                      [&] { return store_.FinishSucceeded(job_.id, options_.worker_id, output); });
  }

  // The policy for a pipeline that did not succeed: a lost lease leaves the job alone; a
  // client's cancel wins over a stop (it is what they asked for); a stopping worker gives
  // the job back (even a failure may be the stop's doing); otherwise the job failed.
  JobRunReport FinishUnsuccessful(const PipelineResult& result) {
    const std::string& stage = result.failed_stage;
    if (lease_lost_) return Finish(JobRunOutcome::kLeaseLost, stage, "");
    if (cancel_requested_) {
      LOG_INFO << "job " << job_.id << " canceled in stage " << stage;
      return FinishWith(JobRunOutcome::kCanceled, stage, result.message,
                        [&] { return store_.FinishCanceled(job_.id, options_.worker_id); });
    }
    if (const std::int64_t resident = over_budget_bytes_.load(); resident > 0) {
      const std::string message =
          "stage " + stage +
          " needed more memory than this worker allows: " + FormatMemory(resident) +
          " resident, over the budget of " + FormatMemory(options_.memory_budget_bytes) +
          " (reconduit-worker --memory-budget). Fewer or smaller photos, or lower "
          "max_image_side / dense_max_image_side options, need less.";
      LOG_WARNING << "job " << job_.id << " failed in stage " << stage << ": " << message;
      return Fail(stage, message);
    }
    if (stop_requested_) {
      LOG_INFO << "job " << job_.id << ": worker stopping; giving the job back";
      return FinishWith(JobRunOutcome::kReleased, stage, result.message,
                        [&] { return store_.ReleaseJob(job_.id, options_.worker_id); });
    }
    if (result.status == StageStatus::kCanceled) {
      return Fail(stage, "stage " + stage + " stopped without a cancel request: " + result.message);
    }
    const std::string message = ExplainDiskFull(result.message);
    LOG_WARNING << "job " << job_.id << " failed in stage " << stage << ": " << message;
    return Fail(stage, message.empty() ? "failed" : message);
  }

  JobRunReport Fail(const std::string& stage, const std::string& message) {
    return FinishWith(JobRunOutcome::kFailed, stage, message, [&] {
      return store_.FinishFailed(job_.id, options_.worker_id, message, stage);
    });
  }

  // Writes a final state through `write` (retried while the store is busy) and maps the
  // store's answer to the outcome: not ours any more is kLeaseLost, other errors kStoreError.
  template <typename Write>
  JobRunReport FinishWith(JobRunOutcome outcome,
                          std::string stage,
                          std::string message,
                          Write write) {
    {
      // A beat after the final write would find the job not ours and cry "lease lost".
      std::lock_guard lock(beat_mutex_);
      finishing_ = true;
    }
    sink_.Close();
    if (lease_lost_) {
      return Finish(JobRunOutcome::kLeaseLost, std::move(stage), "the lease was lost");
    }
    const auto answer = RetryStoreWrite(write);
    const Status& status = StatusOf(answer);
    if (status.ok()) return Finish(outcome, std::move(stage), std::move(message));
    if (status.code() == StatusCode::kFailedPrecondition ||
        status.code() == StatusCode::kNotFound) {
      LOG_WARNING << "job " << job_.id << ": not ours any more: " << status;
      return Finish(JobRunOutcome::kLeaseLost, std::move(stage), status.message());
    }
    LOG_ERROR << "job " << job_.id << ": cannot record the end of the job (" << status
              << "); its lease will expire and it will run again";
    return Finish(JobRunOutcome::kStoreError, std::move(stage), status.message());
  }

  JobRunReport Finish(JobRunOutcome outcome, std::string stage, std::string message) {
    report_.outcome = outcome;
    report_.stage = std::move(stage);
    report_.message = std::move(message);
    report_.seconds = timer_.ElapsedSeconds();
    return report_;
  }

  void Moment(const std::string& name) {
    if (options_.on_moment) options_.on_moment(name);
  }

  JobStore& store_;
  const JobRunnerOptions& options_;
  const DataLayout& layout_;
  const std::atomic<bool>& stop_requested_;
  const Job& job_;
  CancelToken cancel_;
  const Timer timer_;
  JobRunReport report_;
  std::atomic<bool> lease_lost_{false};
  std::atomic<bool> cancel_requested_{false};
  // The resident memory that went over the budget (MemoryWatch); 0 while within it.
  std::atomic<std::int64_t> over_budget_bytes_{0};
  std::mutex beat_mutex_;
  bool finishing_ = false;  // Guarded by beat_mutex_: no beats once the final write begins.
  ProgressSink sink_;       // After the flags its lease-lost callback sets.
  const std::set<std::string> finished_in_store_;
  std::set<std::string> resumed_from_disk_;  // From the plan: stages the runner will skip.
  std::string current_stage_;
  Clock::time_point stage_started_ = Clock::now();
  JobCounts counts_;
};

}  // namespace

JobRunReport JobRunner::Run(const Job& job) {
  CancelToken cancel;
  {
    std::lock_guard lock(running_mutex_);
    running_job_id_ = job.id;
    running_cancel_ = cancel;
  }
  // RequestStop may have come between the claim and here.
  if (stop_requested_) cancel.RequestCancel();
  JobRunReport report = JobRun(store_, options_, layout_, stop_requested_, job, cancel).Execute();
  std::lock_guard lock(running_mutex_);
  running_job_id_.clear();
  running_cancel_ = CancelToken();
  return report;
}

}  // namespace reconduit
