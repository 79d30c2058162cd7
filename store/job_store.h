// The persistent job store shared by reconduit-server and reconduit-worker.
//
// The server creates jobs (after the photos are safe on disk), lists them, reads their status
// and events, cancels, restarts and deletes them. Workers claim the oldest queued job with a
// lease, heart-beat to keep it, record progress and events, mark stages finished (so that a
// later run resumes after them) and finally finish the job. The store enforces the job state
// machine (schema/README.md):
//
//   queued --claim--> running --FinishSucceeded--> succeeded
//     ^  |               |  |----FinishFailed----> failed    --RestartJob--> queued
//     |  |               |  `----FinishCanceled--> canceled  --RestartJob--> queued
//     |  `--RequestCancel----------------------->  canceled
//     `------ lease expired (attempts + 1 < max_attempts), ReleaseJob
//             lease expired at max_attempts -> failed; lease expired after a cancel request
//             -> canceled
//
// Only the worker that holds a job's lease may change its progress or finish it; every such
// call names the worker and fails with kFailedPrecondition once the lease is lost (another
// worker may be running the job by then).
//
// Errors are values: kNotFound (no such job), kFailedPrecondition (wrong state, lease lost;
// HTTP 409), kInvalidArgument (bad input), kResourceExhausted (queue full, or the database
// stayed busy past the busy timeout; HTTP 503), kInternal (I/O failure, corrupt file).
//
// Times are Unix epoch milliseconds (UTC) from the store's clock. Leases compare times written
// by different processes, so hosts sharing a database need synchronised clocks (NTP); a lease
// should be several times longer than the heartbeat interval plus any expected clock skew.
#ifndef RECONDUIT_STORE_JOB_STORE_H_
#define RECONDUIT_STORE_JOB_STORE_H_

#include "core/image/photo_metadata.h"
#include "core/util/logging.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

// ---- Job states ---------------------------------------------------------------------------------

enum class JobState { kQueued = 0, kRunning, kSucceeded, kFailed, kCanceled };
inline constexpr int kNumJobStates = 5;

// "queued", "running", "succeeded", "failed", "canceled": the names used in the database and
// the HTTP API.
std::string_view JobStateName(JobState state);
// The inverse of JobStateName; nullopt for any other text.
std::optional<JobState> ParseJobState(std::string_view name);
// succeeded, failed and canceled are final: only RestartJob (failed, canceled) leaves them.
bool IsFinalState(JobState state);

// ---- Job ids ------------------------------------------------------------------------------------

// A new job id: 128 bits from std::random_device as 32 lower-case hex digits. Ids are
// unguessable, so knowing one is the capability to see the job. Thread-safe.
std::string NewJobId();
// True for exactly 32 lower-case hex digits (the only ids the store accepts or returns).
bool IsValidJobId(std::string_view id);

// ---- Records ------------------------------------------------------------------------------------

// "accepted" or "rejected" (PhotoMetadata::accepted): the names used in the database and the
// HTTP API.
std::string_view ImageStatusName(bool accepted);

// One uploaded photo (a row of `images`).
struct JobImageRecord {
  // 0-based position in the upload; unique within a job.
  int index = 0;
  // The client's file name, for display only; never used as a path.
  std::string original_name;
  // Generated file name under data/jobs/<id>/input/, e.g. "0001.jpg": no '/', '\\', "." or "..".
  std::string stored_name;
  // Size, pixel size (0 x 0 when the header could not be read: NULL in the database), EXIF
  // focal prior, make, model, acceptance and the reason for a rejection ("truncated JPEG").
  // photo.focal_source is not stored (empty when read back).
  PhotoMetadata photo;

  friend bool operator==(const JobImageRecord&, const JobImageRecord&) = default;
};

// The figures of a job shown by the API (`counts` in its JSON), one named field per figure;
// unset fields are not shown. Stored and served as a JSON object with these very field names
// (ToJson/FromJson), so the API's names are the C++ ones. Filled by the worker as stages finish
// (worker/job_runner.h); a new figure is a new field here.
struct JobCounts {
  std::optional<std::int64_t> images;           // Photos accepted (ingest).
  std::optional<std::int64_t> rejected_images;  // Photos rejected (ingest).
  std::optional<std::int64_t> features;         // Features detected (features).
  std::optional<std::int64_t> candidate_pairs;  // Image pairs to match (pairs).
  std::optional<std::int64_t> matched_pairs;    // Pairs with verified matches (matching).
  std::optional<std::int64_t> inlier_matches;   // Verified matches (matching).
  std::optional<std::int64_t> registered;       // Cameras registered.
  std::optional<std::int64_t> points;           // 3D points.
  std::optional<std::int64_t> faces;            // Mesh faces.
  std::optional<std::int64_t> models;           // Separate models reconstructed.
  std::optional<std::int64_t> result_files;     // Files in result.zip (packaging).

  bool empty() const;
  // Sets the fields set in `patch` (a JSON merge patch of ToJson()s).
  void Merge(const JobCounts& patch);
  // The set fields, {"images": 12, ...}; {} when none.
  nlohmann::json ToJson() const;
  // The fields named in `json` that hold integers; anything else is ignored.
  static JobCounts FromJson(const nlohmann::json& json);

  friend bool operator==(const JobCounts&, const JobCounts&) = default;
};

// A job as stored (a row of `jobs`).
struct Job {
  std::string id;
  JobState state = JobState::kQueued;
  // Pipeline options as the client sent them (validated by the server before CreateJob).
  nlohmann::json options = nlohmann::json::object();
  std::int64_t created_at_ms = 0;
  // When the job last entered the queue (creation or restart); claims take the smallest.
  std::int64_t queued_at_ms = 0;
  // Start of the latest run; end of the latest run (set in final states only).
  std::optional<std::int64_t> started_at_ms;
  std::optional<std::int64_t> finished_at_ms;
  std::int64_t updated_at_ms = 0;
  // The stage being run, or the last one run; empty before the first run.
  std::string stage;
  // Overall progress in [0, 1].
  double progress = 0.0;
  // Per-stage progress and timings: {"features": {"progress": 1, "seconds": 12.5}, ...}.
  nlohmann::json stage_progress = nlohmann::json::object();
  // Stages whose output is complete, in the order they finished: a new run skips them.
  std::vector<std::string> finished_stages;
  // Runs lost because the worker stopped heart-beating. A job runs at most max_attempts times.
  int attempts = 0;
  int max_attempts = 3;
  // The worker holding the lease and when it expires; set exactly while running.
  std::string lease_owner;
  std::optional<std::int64_t> lease_until_ms;
  // A cancel was requested while running; the worker stops at its next check.
  bool cancel_requested = false;
  // Why the job failed and the stage it failed in (failed jobs; empty otherwise).
  std::string error;
  std::string error_stage;
  // Accepted photos.
  int image_count = 0;
  // Result counts (registered cameras, points, faces, ...).
  JobCounts counts;
  // Size and SHA-256 (64 lower-case hex digits) of result.zip; set when succeeded.
  std::optional<std::int64_t> result_bytes;
  std::string result_sha256;
};

// What CreateJob needs.
struct NewJob {
  // Empty: the store generates one (NewJobId). The server usually generates the id first with
  // NewJobId() to name the job's folder, writes and fsyncs the photos, then passes it here.
  std::string id;
  // Must be a JSON object (or null, stored as {}).
  nlohmann::json options = nlohmann::json::object();
  // How many runs a job gets before a lost worker fails it; [1, 100].
  int max_attempts = 3;
  // All photos of the upload, accepted and rejected; at least one must be accepted.
  std::vector<JobImageRecord> images;
  // When > 0 and this many jobs are already queued, CreateJob fails with kResourceExhausted
  // (the server's queue limit, checked in the same transaction as the insert).
  std::int64_t max_queued_jobs = 0;
};

// A page of ListJobs.
struct JobListQuery {
  // Page size, [1, 1000].
  int limit = 50;
  // Jobs to skip, >= 0.
  std::int64_t offset = 0;
  // Only jobs in this state, when set.
  std::optional<JobState> state;
};

struct JobPage {
  // Newest first (created_at descending).
  std::vector<Job> jobs;
  // Jobs matching the query in total (for "page 2 of 7").
  std::int64_t total = 0;
};

// What a worker learns from Heartbeat.
struct HeartbeatReply {
  // False when the job is no longer this worker's (lease expired and taken or requeued, job
  // finished or deleted): the worker must stop working on it at once, without finishing it.
  bool owned = false;
  // True when a client asked to cancel: stop and call FinishCanceled.
  bool cancel_requested = false;
  // The new lease expiry when owned.
  std::optional<std::int64_t> lease_until_ms;
};

// A progress report from the lease owner.
struct JobProgressUpdate {
  // The stage now running; empty keeps the current one.
  std::string stage;
  // Overall progress, clamped to [0, 1].
  double progress = 0.0;
  // RFC 7396 merge patch applied to Job::stage_progress, e.g. {"features": {"progress": 0.4}};
  // null for none. Must be an object or null.
  nlohmann::json stage_progress;
  // Set fields replace Job::counts' (e.g. registered = 12); empty for none.
  JobCounts counts;
};

// What a successful job produced.
struct JobOutput {
  // Size of result.zip in bytes, >= 0.
  std::int64_t result_bytes = 0;
  // SHA-256 of result.zip, 64 lower-case hex digits.
  std::string result_sha256;
  // Set fields replace Job::counts'; empty for none.
  JobCounts counts;
};

// A log line for a job (a row of `job_events`).
struct JobEvent {
  // Increases across the whole database; page with ListEvents(job, after_id = last id seen).
  std::int64_t id = 0;
  std::string job_id;
  std::int64_t time_ms = 0;
  // The stage it came from; empty for job-level events (queued, claimed, canceled, ...).
  std::string stage;
  LogLevel level = LogLevel::kInfo;
  std::string message;
  // Overall progress at that moment, when known.
  std::optional<double> progress;
};

// What AppendEvent needs (id, job and time are filled in by the store).
struct NewEvent {
  std::string stage;
  LogLevel level = LogLevel::kInfo;
  std::string message;
  std::optional<double> progress;
};

// "debug", "info", "warning", "error": event levels as stored and served.
std::string_view EventLevelName(LogLevel level);

// Figures for /metrics.
struct QueueStats {
  // Number of jobs in each state, indexed by static_cast<int>(JobState).
  std::array<std::int64_t, kNumJobStates> jobs_by_state{};
  // Creation (or restart) time of the job that has waited longest; unset when none is queued.
  std::optional<std::int64_t> oldest_queued_at_ms;

  std::int64_t Count(JobState state) const { return jobs_by_state[static_cast<int>(state)]; }
  // Jobs waiting for a worker.
  std::int64_t QueueLength() const { return Count(JobState::kQueued); }
};

// What a lease sweep did to running jobs whose lease had expired.
struct SweepResult {
  // Back to queued with attempts + 1.
  std::int64_t requeued = 0;
  // Failed because the job had used max_attempts runs.
  std::int64_t failed = 0;
  // Canceled because a cancel had been requested before the worker vanished.
  std::int64_t canceled = 0;
};

// ---- The store ----------------------------------------------------------------------------------

// Persistent jobs, photos and events.
//
// Thread-safety: every method may be called from any number of threads at once on one instance
// (the SQLite implementation hands each call its own connection from a pool). Any number of
// processes may open the same database file at once; a job is claimed by exactly one of them.
// Do not carry an open store across fork(): open a new one in the child.
class JobStore {
 public:
  virtual ~JobStore() = default;

  // ---- Server side ----

  // Inserts a queued job and its photo rows in one transaction: either all become visible or
  // nothing does. Records a "queued" event.
  // @return the stored job; kInvalidArgument (bad id, options not an object, no accepted photo,
  //         unsafe stored name, duplicate photo index), kAlreadyExists (id taken),
  //         kResourceExhausted (max_queued_jobs reached).
  virtual Result<Job> CreateJob(const NewJob& job) = 0;

  // @return the job, or kNotFound (also for malformed ids).
  virtual Result<Job> GetJob(std::string_view id) = 0;

  // A job's photos in upload order; kNotFound when the job does not exist.
  virtual Result<std::vector<JobImageRecord>> ListImages(std::string_view job_id) = 0;

  // Jobs newest first, one page at a time, with the total count.
  virtual Result<JobPage> ListJobs(const JobListQuery& query) = 0;

  // Cancels a job. queued -> canceled at once; running -> sets cancel_requested (the worker
  // stops at its next check and calls FinishCanceled; asking again is harmless).
  // @return the state after the call (kCanceled or kRunning); kFailedPrecondition for a job
  //         that is already succeeded, failed or canceled; kNotFound.
  virtual Result<JobState> RequestCancel(std::string_view id) = 0;

  // Queues a failed or canceled job again: attempts, error, result and cancel flag are reset,
  // the finished stages and their progress are kept so the next run resumes after them. The job
  // joins the end of the queue.
  // @return the job as queued; kFailedPrecondition in any other state; kNotFound.
  virtual Result<Job> RestartJob(std::string_view id) = 0;

  // Deletes a job with its photos and events (ON DELETE CASCADE). Refused while running — the
  // worker may still be writing into the job's folder: cancel first, then delete once it is
  // canceled. The caller removes the job's files afterwards.
  // @return the state the job had; kFailedPrecondition while running; kNotFound.
  virtual Result<JobState> DeleteJob(std::string_view id) = 0;

  // ---- Worker side ----

  // Claims the oldest queued job (by queued_at) for `worker_id`, atomically: under concurrent
  // callers in any number of threads and processes each job goes to exactly one worker. The job
  // becomes running with lease_owner = worker_id and lease_until = now + lease. Runs
  // SweepExpiredLeases first, in the same transaction, so a job lost by a dead worker is
  // requeued (or failed) and claimable in the same call.
  // @param worker_id  a stable, unique name for the worker, e.g. "host:pid:random".
  // @param lease      > 0; the worker must heart-beat well within it.
  // @return the claimed job (its finished_stages say where to resume), nullopt when the queue is
  //         empty.
  virtual Result<std::optional<Job>> ClaimNextJob(std::string_view worker_id,
                                                  std::chrono::milliseconds lease) = 0;

  // Extends the lease to now + lease when `worker_id` still holds it. A lease that ran out but
  // has not been swept yet is still held (nobody else has the job), so a late heartbeat revives
  // it; once a sweep or another worker's claim has taken the job, the answer is owned = false.
  // @return whether the worker still owns the job and whether a cancel was requested. Not
  //         owning the job (or its not existing) is a normal answer, not an error.
  virtual Result<HeartbeatReply> Heartbeat(std::string_view job_id,
                                           std::string_view worker_id,
                                           std::chrono::milliseconds lease) = 0;

  // Records the current stage, overall progress and per-stage progress/counts.
  // @return kFailedPrecondition when `worker_id` does not hold the lease; kNotFound;
  //         kInvalidArgument when a patch is not an object.
  virtual Status RecordProgress(std::string_view job_id,
                                std::string_view worker_id,
                                const JobProgressUpdate& update) = 0;

  // Marks `stage` finished: its output is complete on disk and a later run may skip it. Adds it
  // to finished_stages (once), sets its stage_progress to {"progress": 1, "seconds": seconds}
  // and records an event. Same errors as RecordProgress.
  virtual Status MarkStageFinished(std::string_view job_id,
                                   std::string_view worker_id,
                                   std::string_view stage,
                                   double seconds) = 0;

  // The finished stages in the order they finished; kNotFound.
  virtual Result<std::vector<std::string>> ListFinishedStages(std::string_view job_id) = 0;

  // running -> succeeded with the result's size, hash and counts; progress becomes 1.
  // @return kFailedPrecondition when `worker_id` does not hold the lease (the job may be
  //         running elsewhere by now); kInvalidArgument for a malformed hash; kNotFound.
  virtual Status FinishSucceeded(std::string_view job_id,
                                 std::string_view worker_id,
                                 const JobOutput& output) = 0;

  // running -> failed with a non-empty message and the stage it came from (may be empty).
  // Same ownership errors as FinishSucceeded.
  virtual Status FinishFailed(std::string_view job_id,
                              std::string_view worker_id,
                              std::string_view error,
                              std::string_view stage) = 0;

  // running -> canceled, normally after Heartbeat reported cancel_requested.
  // Same ownership errors as FinishSucceeded.
  virtual Status FinishCanceled(std::string_view job_id, std::string_view worker_id) = 0;

  // Gives a running job back without spending an attempt (a worker shutting down cleanly):
  // running -> queued, keeping its place in the queue; running -> canceled when a cancel had
  // been requested.
  // @return the new state; same ownership errors as FinishSucceeded.
  virtual Result<JobState> ReleaseJob(std::string_view job_id, std::string_view worker_id) = 0;

  // ---- Events ----

  // Appends a log line to a job's events (anyone may: worker or server).
  // @return the event id; kNotFound when the job does not exist.
  virtual Result<std::int64_t> AppendEvent(std::string_view job_id, const NewEvent& event) = 0;

  // Events with id > after_id in id order, at most `limit` ([1, 1000]).
  // @return kNotFound when the job does not exist; kInvalidArgument for a bad limit.
  virtual Result<std::vector<JobEvent>> ListEvents(std::string_view job_id,
                                                   std::int64_t after_id,
                                                   int limit) = 0;

  // ---- Maintenance and metrics ----

  // Jobs by state and the age of the queue.
  virtual Result<QueueStats> GetQueueStats() = 0;

  // Handles every running job whose lease has expired: canceled if a cancel was requested,
  // else attempts + 1 and back to queued (keeping its place), or failed with an error naming
  // the lost worker once attempts reaches max_attempts. Each gets a warning event. ClaimNextJob
  // does this too; call it at start-up and periodically so that status pages are accurate even
  // when no worker is claiming.
  virtual Result<SweepResult> SweepExpiredLeases() = 0;
};

// ---- SQLite implementation ----------------------------------------------------------------------

struct SqliteJobStoreOptions {
  // How long a call waits for another connection's write lock before giving up with
  // kResourceExhausted. Write transactions are short (milliseconds), so 5 s only runs out when
  // something is badly wrong.
  int busy_timeout_ms = 5000;

  // PRAGMA synchronous. FULL (the default) fsyncs the WAL at every commit, so a job the server
  // has answered 201 for survives a power cut or kernel crash, as its fsynced photos do. NORMAL
  // is also crash-consistent in WAL mode and survives any process crash (kill -9), but the last
  // commits before a power cut may roll back; it saves one fsync per write.
  bool synchronous_full = true;

  // The clock, Unix epoch milliseconds; empty for the system clock. Tests inject a fake clock
  // to expire leases without sleeping. Called from any thread.
  std::function<std::int64_t()> now_ms;
};

// Opens (creating if needed) the SQLite job database at `path` and brings its schema up to
// date (ApplyMigrations with the embedded schema/sql migrations). Sets WAL mode (persistent in
// the file), busy_timeout, foreign_keys=ON and the synchronous level on every connection.
// @param path  a file path; ":memory:" and URI names are refused (each pooled connection
//              would see a different database).
// @return the store; kFailedPrecondition for a database written by a newer Reconduit or by
//         another program; kInternal naming the problem for a file that is not a database or
//         cannot be opened.
Result<std::unique_ptr<JobStore>> OpenSqliteJobStore(const std::string& path,
                                                     const SqliteJobStoreOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_STORE_JOB_STORE_H_
