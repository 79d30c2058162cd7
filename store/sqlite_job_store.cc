// The SQLite implementation of JobStore (OpenSqliteJobStore in job_store.h).
//
// Concurrency model:
// - Threads: a pool of connections. Each call borrows an idle connection (opening a new one
//   when none is idle) and returns it afterwards, so calls from different threads run on
//   different connections and WAL lets readers proceed while one writer commits.
// - Processes: every read-modify-write runs in a BEGIN IMMEDIATE transaction, which takes the
//   database's single write lock up front (waiting up to busy_timeout). Claiming, finishing,
//   canceling and sweeping are therefore serialised across all threads and processes, which is
//   what makes "each job is claimed exactly once" hold. Single-statement writes run in
//   autocommit mode, which also takes the write lock before reading.
// - A call that still meets SQLITE_BUSY (busy timeout exhausted, or one of the rare cases where
//   SQLite does not consult the busy handler) is retried a few times from the start of its
//   transaction, each try with the whole busy timeout, then reported as kResourceExhausted.
//   (One budget shared by all tries starved a claim of four processes claiming in a loop under
//   the sanitizers: JobStoreConcurrency.ProcessesClaimEachJobOnceWithoutBusyErrors. So an
//   upload behind a lock held by another process is answered 503 after about 20 s.)
#include "core/util/logging.h"

#include "store/job_store.h"
#include "store/migrations.h"
#include "store/sqlite_util.h"
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

using json = nlohmann::json;

// Retries of a whole call after SQLITE_BUSY, on top of SQLite's own busy_timeout wait.
constexpr int kMaxBusyRetries = 3;
// Idle connections kept open per store; more are closed when returned.
constexpr std::size_t kMaxIdleConnections = 16;
constexpr int kMaxPageSize = 1000;
constexpr int kMaxAttemptsLimit = 100;

// Column list shared by every query that reads whole jobs (see ReadJob).
constexpr std::string_view kJobColumns =
    "id, state, options, created_at, queued_at, started_at, finished_at, updated_at, stage, "
    "progress, stage_progress, finished_stages, attempts, max_attempts, lease_owner, "
    "lease_until, cancel_requested, error, error_stage, image_count, counts, result_bytes, "
    "result_sha256";

// Builds SQL text from constant pieces (never from values: those are bound).
std::string Sql(std::initializer_list<std::string_view> parts) {
  std::string sql;
  for (std::string_view part : parts) sql += part;
  return sql;
}

std::string Quote(std::string_view text) { return "'" + std::string(text) + "'"; }

std::string FormatSeconds(double seconds) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.1f s", seconds);
  return buffer;
}

std::int64_t SystemNowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// JSON text for storage; invalid UTF-8 in strings is replaced rather than thrown on.
std::string DumpJson(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

// A merge patch for json_patch(): an object, or {} for "no change".
Result<std::string> PatchText(const json& patch, std::string_view what) {
  if (patch.is_null()) return std::string("{}");
  if (!patch.is_object()) {
    return Status::InvalidArgument(std::string(what) + " must be a JSON object");
  }
  return DumpJson(patch);
}

json ParseStoredJson(const std::string& text, std::string_view column) {
  json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    throw SqliteError(Status::Internal("column " + std::string(column) + " holds invalid JSON"));
  }
  return value;
}

std::vector<std::string> ParseStageList(const std::string& text) {
  const json value = ParseStoredJson(text, "finished_stages");
  std::vector<std::string> stages;
  if (!value.is_array()) return stages;
  for (const json& stage : value) {
    if (stage.is_string()) stages.push_back(stage.get<std::string>());
  }
  return stages;
}

// Reads the kJobColumns of the current row.
Job ReadJob(const Statement& row) {
  Job job;
  job.id = row.Text(0);
  const std::optional<JobState> state = ParseJobState(row.Text(1));
  if (!state) {
    throw SqliteError(
        Status::Internal("job " + job.id + " has unknown state " + Quote(row.Text(1))));
  }
  job.state = *state;
  job.options = ParseStoredJson(row.Text(2), "options");
  job.created_at_ms = row.Int64(3);
  job.queued_at_ms = row.Int64(4);
  job.started_at_ms = row.OptionalInt64(5);
  job.finished_at_ms = row.OptionalInt64(6);
  job.updated_at_ms = row.Int64(7);
  job.stage = row.Text(8);
  job.progress = row.Double(9);
  job.stage_progress = ParseStoredJson(row.Text(10), "stage_progress");
  job.finished_stages = ParseStageList(row.Text(11));
  job.attempts = static_cast<int>(row.Int64(12));
  job.max_attempts = static_cast<int>(row.Int64(13));
  job.lease_owner = row.Text(14);
  job.lease_until_ms = row.OptionalInt64(15);
  job.cancel_requested = row.Int64(16) != 0;
  job.error = row.Text(17);
  job.error_stage = row.Text(18);
  job.image_count = static_cast<int>(row.Int64(19));
  job.counts = JobCounts::FromJson(ParseStoredJson(row.Text(20), "counts"));
  job.result_bytes = row.OptionalInt64(21);
  job.result_sha256 = row.Text(22);
  return job;
}

std::optional<Job> FindJob(SqliteConnection& db, std::string_view id) {
  static const std::string kSql = Sql({"SELECT ", kJobColumns, " FROM jobs WHERE id = ?1"});
  Statement select(db.get(), kSql);
  select.Bind(1, id);
  if (!select.Step()) return std::nullopt;
  return ReadJob(select);
}

std::optional<JobState> FindJobState(SqliteConnection& db, std::string_view id) {
  Statement select(db.get(), "SELECT state FROM jobs WHERE id = ?1");
  select.Bind(1, id);
  if (!select.Step()) return std::nullopt;
  return ParseJobState(select.Text(0));
}

Status JobNotFound(std::string_view id) {
  return Status::NotFound("job " + std::string(id) + " not found");
}

// Why a lease-owner update changed no row: the job is gone, not running, or someone else's.
Status OwnershipError(SqliteConnection& db, std::string_view job_id, std::string_view worker_id) {
  Statement select(db.get(), "SELECT state, lease_owner FROM jobs WHERE id = ?1");
  select.Bind(1, job_id);
  if (!select.Step()) return JobNotFound(job_id);
  const std::string state = select.Text(0);
  const std::string owner = select.Text(1);
  if (state != "running") {
    return Status::FailedPrecondition("job " + std::string(job_id) + " is " + state +
                                      ", no longer running under worker " + Quote(worker_id));
  }
  return Status::FailedPrecondition("job " + std::string(job_id) + " is leased to worker " +
                                    Quote(owner) + ", not " + Quote(worker_id) +
                                    " (the lease expired)");
}

// Runs an UPDATE whose ?1 and ?2 are the job id and the lease owner, and explains a miss.
Status RunOwnedUpdate(SqliteConnection& db,
                      Statement& update,
                      std::string_view job_id,
                      std::string_view worker_id) {
  update.Bind(1, job_id).Bind(2, worker_id);
  update.Run();
  if (db.Changes() > 0) return Status::Ok();
  return OwnershipError(db, job_id, worker_id);
}

std::int64_t InsertEvent(SqliteConnection& db,
                         std::string_view job_id,
                         std::int64_t now,
                         std::string_view stage,
                         LogLevel level,
                         std::string_view message,
                         std::optional<double> progress) {
  Statement insert(db.get(),
                   "INSERT INTO job_events (job_id, time, stage, level, message, progress) "
                   "VALUES (?1, ?2, ?3, ?4, ?5, ?6) RETURNING id");
  insert.Bind(1, job_id).Bind(2, now).BindTextOrNull(3, stage).Bind(4, EventLevelName(level));
  insert.Bind(5, message).Bind(6, progress);
  insert.Step();
  const std::int64_t id = insert.Int64(0);
  insert.Run();
  return id;
}

LogLevel ParseEventLevel(std::string_view name) {
  for (LogLevel level : {LogLevel::kDebug, LogLevel::kInfo, LogLevel::kWarning, LogLevel::kError}) {
    if (EventLevelName(level) == name) return level;
  }
  return LogLevel::kInfo;
}

Status CheckWorker(std::string_view worker_id) {
  if (worker_id.empty()) return Status::InvalidArgument("worker id must not be empty");
  return Status::Ok();
}

Status CheckLease(std::chrono::milliseconds lease) {
  if (lease.count() <= 0) return Status::InvalidArgument("lease must be positive");
  return Status::Ok();
}

bool IsSha256Hex(std::string_view text) {
  return text.size() == 64 && std::all_of(text.begin(), text.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

bool IsSafeStoredName(std::string_view name) {
  return !name.empty() && name != "." && name != ".." &&
         name.find_first_of(std::string_view("/\\\0", 3)) == std::string_view::npos;
}

Status CheckNewJob(const std::string& id, const NewJob& job) {
  if (!IsValidJobId(id)) {
    return Status::InvalidArgument("job id must be 32 lower-case hex digits, got " + Quote(id));
  }
  if (!job.options.is_null() && !job.options.is_object()) {
    return Status::InvalidArgument("options must be a JSON object");
  }
  if (job.max_attempts < 1 || job.max_attempts > kMaxAttemptsLimit) {
    return Status::InvalidArgument("max_attempts must be in [1, " +
                                   std::to_string(kMaxAttemptsLimit) + "], got " +
                                   std::to_string(job.max_attempts));
  }
  bool any_accepted = false;
  for (const JobImageRecord& image : job.images) {
    if (!IsSafeStoredName(image.stored_name)) {
      return Status::InvalidArgument("unsafe stored file name " + Quote(image.stored_name));
    }
    if (image.index < 0 || image.photo.bytes < 0) {
      return Status::InvalidArgument("image " + Quote(image.stored_name) +
                                     " has a negative index or size");
    }
    any_accepted = any_accepted || image.photo.accepted;
  }
  if (!any_accepted) return Status::InvalidArgument("a job needs at least one accepted photo");
  return Status::Ok();
}

// Applies the expiry rules to every running job whose lease ended before `now`. Must run inside
// a BEGIN IMMEDIATE transaction.
SweepResult SweepLocked(SqliteConnection& db, std::int64_t now) {
  struct Expired {
    std::string id;
    std::string owner;
    int attempts = 0;
    int max_attempts = 0;
    bool cancel_requested = false;
    std::string stage;
  };
  std::vector<Expired> expired;
  {
    // `state = 'running'` literally, so that the partial index jobs_running_lease is used.
    Statement select(db.get(),
                     "SELECT id, lease_owner, attempts, max_attempts, cancel_requested, stage "
                     "FROM jobs WHERE state = 'running' AND lease_until < ?1");
    select.Bind(1, now);
    while (select.Step()) {
      expired.push_back({select.Text(0), select.Text(1), static_cast<int>(select.Int64(2)),
                         static_cast<int>(select.Int64(3)), select.Int64(4) != 0, select.Text(5)});
    }
  }
  SweepResult result;
  for (const Expired& job : expired) {
    const std::string lost = "worker " + Quote(job.owner) + " stopped heart-beating";
    const int attempts = job.attempts + 1;
    if (job.cancel_requested) {
      Statement update(db.get(),
                       "UPDATE jobs SET state = 'canceled', finished_at = ?2, updated_at = ?2, "
                       "lease_owner = NULL, lease_until = NULL WHERE id = ?1");
      update.Bind(1, job.id).Bind(2, now).Run();
      InsertEvent(db, job.id, now, job.stage, LogLevel::kWarning,
                  lost + "; job canceled as requested", std::nullopt);
      ++result.canceled;
    } else if (attempts >= job.max_attempts) {
      const std::string error =
          "gave up after " + std::to_string(attempts) + (attempts == 1 ? " run" : " runs") +
          ": the worker stopped heart-beating before the job finished (last: worker " +
          Quote(job.owner) + (job.stage.empty() ? "" : " in stage " + Quote(job.stage)) + ")";
      Statement update(db.get(),
                       "UPDATE jobs SET state = 'failed', attempts = ?2, error = ?3, "
                       "error_stage = ?4, finished_at = ?5, updated_at = ?5, "
                       "lease_owner = NULL, lease_until = NULL WHERE id = ?1");
      update.Bind(1, job.id).Bind(2, attempts).Bind(3, error).BindTextOrNull(4, job.stage);
      update.Bind(5, now).Run();
      InsertEvent(db, job.id, now, job.stage, LogLevel::kError, error, std::nullopt);
      ++result.failed;
    } else {
      // The job keeps its queued_at, so it is next in line again.
      Statement update(db.get(),
                       "UPDATE jobs SET state = 'queued', attempts = ?2, updated_at = ?3, "
                       "lease_owner = NULL, lease_until = NULL WHERE id = ?1");
      update.Bind(1, job.id).Bind(2, attempts).Bind(3, now).Run();
      InsertEvent(db, job.id, now, job.stage, LogLevel::kWarning,
                  lost + " (lease expired); requeued for run " + std::to_string(attempts + 1) +
                      " of at most " + std::to_string(job.max_attempts),
                  std::nullopt);
      ++result.requeued;
    }
  }
  return result;
}

void ConfigureConnection(SqliteConnection& db, const SqliteJobStoreOptions& options) {
  ThrowIfSqliteError(sqlite3_busy_timeout(db.get(), options.busy_timeout_ms), db.get(),
                     "set busy timeout");
  // Per connection, and a no-op inside a transaction: set before any is opened.
  db.Exec("PRAGMA foreign_keys = ON", "enable foreign keys");
  db.Exec(options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL",
          "set synchronous");
}

// Switches the file to WAL (persistent: later connections inherit it). Changing the journal
// mode needs an exclusive lock and does not always wait on the busy handler, so retry for up to
// the busy timeout when several processes open a new file at once.
void EnableWal(SqliteConnection& db, const SqliteJobStoreOptions& options) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(options.busy_timeout_ms);
  std::string mode;
  for (;;) {
    try {
      Statement pragma(db.get(), "PRAGMA journal_mode = WAL");
      if (pragma.Step()) mode = pragma.Text(0);
      break;
    } catch (const SqliteError& e) {
      if (!e.busy() || std::chrono::steady_clock::now() > deadline) {
        throw;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  if (mode != "wal") {
    throw SqliteError(Status::Internal("cannot switch to WAL mode (journal_mode is " + Quote(mode) +
                                       "); the file system may not support shared memory"));
  }
}

// ------------------------------------------------------------------------------------------------

class SqliteJobStore final : public JobStore {
 public:
  SqliteJobStore(std::string path, SqliteJobStoreOptions options, SqliteConnection first)
      : path_(std::move(path)), options_(std::move(options)) {
    idle_.push_back(std::make_unique<SqliteConnection>(std::move(first)));
  }

  Result<Job> CreateJob(const NewJob& job) override;
  Result<Job> GetJob(std::string_view id) override;
  Result<std::vector<JobImageRecord>> ListImages(std::string_view job_id) override;
  Result<JobPage> ListJobs(const JobListQuery& query) override;
  Result<JobState> RequestCancel(std::string_view id) override;
  Result<Job> RestartJob(std::string_view id) override;
  Result<JobState> DeleteJob(std::string_view id) override;
  Result<std::optional<Job>> ClaimNextJob(std::string_view worker_id,
                                          std::chrono::milliseconds lease) override;
  Result<HeartbeatReply> Heartbeat(std::string_view job_id,
                                   std::string_view worker_id,
                                   std::chrono::milliseconds lease) override;
  Status RecordProgress(std::string_view job_id,
                        std::string_view worker_id,
                        const JobProgressUpdate& update) override;
  Status MarkStageFinished(std::string_view job_id,
                           std::string_view worker_id,
                           std::string_view stage,
                           double seconds) override;
  Result<std::vector<std::string>> ListFinishedStages(std::string_view job_id) override;
  Status FinishSucceeded(std::string_view job_id,
                         std::string_view worker_id,
                         const JobOutput& output) override;
  Status FinishFailed(std::string_view job_id,
                      std::string_view worker_id,
                      std::string_view error,
                      std::string_view stage) override;
  Status FinishCanceled(std::string_view job_id, std::string_view worker_id) override;
  Result<JobState> ReleaseJob(std::string_view job_id, std::string_view worker_id) override;
  Result<std::int64_t> AppendEvent(std::string_view job_id, const NewEvent& event) override;
  Result<std::vector<JobEvent>> ListEvents(std::string_view job_id,
                                           std::int64_t after_id,
                                           int limit) override;
  Result<QueueStats> GetQueueStats() override;
  Result<SweepResult> SweepExpiredLeases() override;

 private:
  // A connection borrowed from the pool for the duration of one call.
  class Borrowed {
   public:
    explicit Borrowed(SqliteJobStore& store) : store_(store), connection_(store.Acquire()) {}
    Borrowed(const Borrowed&) = delete;
    Borrowed& operator=(const Borrowed&) = delete;
    ~Borrowed() { store_.Release(std::move(connection_)); }
    SqliteConnection& get() { return *connection_; }

   private:
    SqliteJobStore& store_;
    std::unique_ptr<SqliteConnection> connection_;
  };

  std::unique_ptr<SqliteConnection> Acquire();
  void Release(std::unique_ptr<SqliteConnection> connection) noexcept;
  std::int64_t Now() const { return options_.now_ms ? options_.now_ms() : SystemNowMs(); }

  // Runs fn(connection) and turns exceptions into the call's Status (prefixed with `what`);
  // retries the whole call when the database stayed busy. fn returns Status or Result<T>.
  template <typename Fn>
  std::invoke_result_t<Fn&, SqliteConnection&> Run(std::string_view what, Fn&& fn);

  // The shared body of FinishSucceeded/Failed/Canceled: `update` has ?1 = job, ?2 = worker.
  Status FinishOwned(std::string_view what,
                     std::string_view job_id,
                     std::string_view worker_id,
                     const std::function<void(Statement&, std::int64_t now)>& bind,
                     std::string_view sql,
                     LogLevel level,
                     const std::string& event_stage,
                     const std::string& event_message);

  const std::string path_;
  const SqliteJobStoreOptions options_;
  std::mutex mutex_;  // Guards idle_.
  std::vector<std::unique_ptr<SqliteConnection>> idle_;
};

std::unique_ptr<SqliteConnection> SqliteJobStore::Acquire() {
  {
    std::lock_guard lock(mutex_);
    if (!idle_.empty()) {
      std::unique_ptr<SqliteConnection> connection = std::move(idle_.back());
      idle_.pop_back();
      return connection;
    }
  }
  // Opened outside the lock: other threads keep borrowing while this one waits on the disk.
  auto connection = std::make_unique<SqliteConnection>(SqliteConnection::Open(path_));
  ConfigureConnection(*connection, options_);
  return connection;
}

void SqliteJobStore::Release(std::unique_ptr<SqliteConnection> connection) noexcept {
  if (connection == nullptr) return;
  // Transactions end inside each call (commit or the Transaction destructor's rollback). If one
  // is somehow still open, do not hand it to the next caller.
  if (!connection->InAutocommit()) return;
  std::lock_guard lock(mutex_);
  if (idle_.size() < kMaxIdleConnections) idle_.push_back(std::move(connection));
}

template <typename Fn>
std::invoke_result_t<Fn&, SqliteConnection&> SqliteJobStore::Run(std::string_view what, Fn&& fn) {
  using R = std::invoke_result_t<Fn&, SqliteConnection&>;
  for (int attempt = 0;; ++attempt) {
    Status error;
    bool busy = false;
    try {
      Borrowed connection(*this);
      return fn(connection.get());
    } catch (const SqliteError& e) {
      error = e.status();
      busy = e.busy();
    } catch (const std::exception& e) {
      error = Status::Internal(e.what());
    }
    if (busy && attempt < kMaxBusyRetries) {
      LOG_WARNING << "job store: " << what << ": " << error.message() << "; retrying";
      std::this_thread::sleep_for(std::chrono::milliseconds(20 << attempt));
      continue;
    }
    return R(Status(error.code(), std::string(what) + ": " + error.message()));
  }
}

Result<Job> SqliteJobStore::CreateJob(const NewJob& new_job) {
  return Run("create job", [&](SqliteConnection& db) -> Result<Job> {
    const std::string id = new_job.id.empty() ? NewJobId() : new_job.id;
    if (Status s = CheckNewJob(id, new_job); !s.ok()) return s;
    const std::string options = new_job.options.is_null() ? "{}" : DumpJson(new_job.options);
    const auto accepted =
        std::count_if(new_job.images.begin(), new_job.images.end(),
                      [](const JobImageRecord& image) { return image.photo.accepted; });
    const auto rejected = static_cast<std::int64_t>(new_job.images.size()) - accepted;

    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    if (FindJobState(db, id)) return Status::AlreadyExists("job " + id + " already exists");
    if (new_job.max_queued_jobs > 0) {
      Statement count(db.get(), "SELECT count(*) FROM jobs WHERE state = 'queued'");
      count.Step();
      if (count.Int64(0) >= new_job.max_queued_jobs) {
        return Status::ResourceExhausted("the queue is full: " + std::to_string(count.Int64(0)) +
                                         " jobs are waiting (limit " +
                                         std::to_string(new_job.max_queued_jobs) + ")");
      }
    }
    Statement insert(db.get(),
                     "INSERT INTO jobs (id, state, options, created_at, queued_at, updated_at, "
                     "max_attempts, image_count) VALUES (?1, 'queued', ?2, ?3, ?3, ?3, ?4, ?5)");
    insert.Bind(1, id).Bind(2, options).Bind(3, now).Bind(4, new_job.max_attempts);
    insert.Bind(5, static_cast<std::int64_t>(accepted)).Run();

    Statement image_insert(
        db.get(),
        "INSERT INTO images (job_id, idx, original_name, stored_name, bytes, width, height, "
        "exif_focal_px, make, model, status, reject_reason) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)");
    for (const JobImageRecord& image : new_job.images) {
      image_insert.Reset();
      image_insert.Bind(1, id).Bind(2, image.index).Bind(3, image.original_name);
      const PhotoMetadata& photo = image.photo;
      const bool sized = photo.width > 0 && photo.height > 0;  // NULL size when unknown.
      image_insert.Bind(4, image.stored_name).Bind(5, photo.bytes);
      image_insert.Bind(6, sized ? std::optional<int>(photo.width) : std::nullopt);
      image_insert.Bind(7, sized ? std::optional<int>(photo.height) : std::nullopt);
      image_insert.Bind(8, photo.exif_focal_px);
      image_insert.BindTextOrNull(9, photo.make).BindTextOrNull(10, photo.model);
      image_insert.Bind(11, ImageStatusName(photo.accepted));
      image_insert.BindTextOrNull(12, photo.reason);
      image_insert.Run();
    }
    std::string message =
        "queued with " + std::to_string(accepted) + (accepted == 1 ? " photo" : " photos");
    if (rejected > 0) message += " (" + std::to_string(rejected) + " rejected)";
    InsertEvent(db, id, now, "", LogLevel::kInfo, message, 0.0);
    std::optional<Job> job = FindJob(db, id);
    transaction.Commit();
    return std::move(*job);
  });
}

Result<Job> SqliteJobStore::GetJob(std::string_view id) {
  if (!IsValidJobId(id)) return JobNotFound(id);
  return Run("get job", [&](SqliteConnection& db) -> Result<Job> {
    std::optional<Job> job = FindJob(db, id);
    if (!job) return JobNotFound(id);
    return std::move(*job);
  });
}

Result<std::vector<JobImageRecord>> SqliteJobStore::ListImages(std::string_view job_id) {
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  return Run("list images", [&](SqliteConnection& db) -> Result<std::vector<JobImageRecord>> {
    Transaction transaction(db, Transaction::Mode::kDeferred);  // One consistent snapshot.
    if (!FindJobState(db, job_id)) return JobNotFound(job_id);
    Statement select(db.get(),
                     "SELECT idx, original_name, stored_name, bytes, width, height, "
                     "exif_focal_px, make, model, status, reject_reason "
                     "FROM images WHERE job_id = ?1 ORDER BY idx");
    select.Bind(1, job_id);
    std::vector<JobImageRecord> images;
    while (select.Step()) {
      JobImageRecord image;
      image.index = static_cast<int>(select.Int64(0));
      image.original_name = select.Text(1);
      image.stored_name = select.Text(2);
      PhotoMetadata& photo = image.photo;
      photo.bytes = select.Int64(3);
      if (!select.IsNull(4)) photo.width = static_cast<int>(select.Int64(4));
      if (!select.IsNull(5)) photo.height = static_cast<int>(select.Int64(5));
      photo.exif_focal_px = select.OptionalDouble(6);
      photo.make = select.Text(7);
      photo.model = select.Text(8);
      photo.accepted = select.Text(9) != "rejected";
      photo.reason = select.Text(10);
      images.push_back(std::move(image));
    }
    return images;
  });
}

Result<JobPage> SqliteJobStore::ListJobs(const JobListQuery& query) {
  if (query.limit < 1 || query.limit > kMaxPageSize) {
    return Status::InvalidArgument("limit must be in [1, " + std::to_string(kMaxPageSize) + "]");
  }
  if (query.offset < 0) return Status::InvalidArgument("offset must not be negative");
  return Run("list jobs", [&](SqliteConnection& db) -> Result<JobPage> {
    std::optional<std::string> state;
    if (query.state) state = std::string(JobStateName(*query.state));
    Transaction transaction(db, Transaction::Mode::kDeferred);  // Count and page agree.
    JobPage page;
    {
      Statement count(db.get(), "SELECT count(*) FROM jobs WHERE ?1 IS NULL OR state = ?1");
      count.Bind(1, state);
      count.Step();
      page.total = count.Int64(0);
    }
    static const std::string kSql =
        Sql({"SELECT ", kJobColumns,
             " FROM jobs WHERE ?1 IS NULL OR state = ?1 "
             "ORDER BY created_at DESC, rowid DESC LIMIT ?2 OFFSET ?3"});
    Statement select(db.get(), kSql);
    select.Bind(1, state).Bind(2, query.limit).Bind(3, query.offset);
    while (select.Step()) page.jobs.push_back(ReadJob(select));
    return page;
  });
}

Result<JobState> SqliteJobStore::RequestCancel(std::string_view id) {
  if (!IsValidJobId(id)) return JobNotFound(id);
  return Run("cancel job", [&](SqliteConnection& db) -> Result<JobState> {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    const std::optional<JobState> state = FindJobState(db, id);
    if (!state) return JobNotFound(id);
    JobState result = *state;
    if (*state == JobState::kQueued) {
      Statement update(db.get(),
                       "UPDATE jobs SET state = 'canceled', cancel_requested = 1, "
                       "finished_at = ?2, updated_at = ?2 WHERE id = ?1");
      update.Bind(1, id).Bind(2, now).Run();
      InsertEvent(db, id, now, "", LogLevel::kInfo, "canceled while queued", std::nullopt);
      result = JobState::kCanceled;
    } else if (*state == JobState::kRunning) {
      Statement update(db.get(),
                       "UPDATE jobs SET cancel_requested = 1, updated_at = ?2 WHERE id = ?1 "
                       "AND cancel_requested = 0");
      update.Bind(1, id).Bind(2, now).Run();
      if (db.Changes() > 0) {
        InsertEvent(db, id, now, "", LogLevel::kInfo,
                    "cancel requested; waiting for the worker to stop", std::nullopt);
      }
    } else {
      return Status::FailedPrecondition("job " + std::string(id) + " is already " +
                                        std::string(JobStateName(*state)) +
                                        "; only queued or running jobs can be canceled");
    }
    transaction.Commit();
    return result;
  });
}

Result<Job> SqliteJobStore::RestartJob(std::string_view id) {
  if (!IsValidJobId(id)) return JobNotFound(id);
  return Run("restart job", [&](SqliteConnection& db) -> Result<Job> {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    const std::optional<JobState> state = FindJobState(db, id);
    if (!state) return JobNotFound(id);
    if (*state != JobState::kFailed && *state != JobState::kCanceled) {
      return Status::FailedPrecondition("job " + std::string(id) + " is " +
                                        std::string(JobStateName(*state)) +
                                        "; only failed or canceled jobs can be restarted");
    }
    // finished_stages and stage_progress stay: the next run resumes after them.
    Statement update(db.get(),
                     "UPDATE jobs SET state = 'queued', queued_at = ?2, updated_at = ?2, "
                     "finished_at = NULL, attempts = 0, cancel_requested = 0, error = NULL, "
                     "error_stage = NULL, result_bytes = NULL, result_sha256 = NULL "
                     "WHERE id = ?1");
    update.Bind(1, id).Bind(2, now).Run();
    std::optional<Job> job = FindJob(db, id);
    std::string message = "restarted";
    if (!job->finished_stages.empty()) {
      message += "; resuming after stage " + Quote(job->finished_stages.back());
    }
    InsertEvent(db, id, now, "", LogLevel::kInfo, message, job->progress);
    transaction.Commit();
    return std::move(*job);
  });
}

Result<JobState> SqliteJobStore::DeleteJob(std::string_view id) {
  if (!IsValidJobId(id)) return JobNotFound(id);
  return Run("delete job", [&](SqliteConnection& db) -> Result<JobState> {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::optional<JobState> state = FindJobState(db, id);
    if (!state) return JobNotFound(id);
    if (*state == JobState::kRunning) {
      return Status::FailedPrecondition("job " + std::string(id) +
                                        " is running; cancel it and delete it once it has "
                                        "stopped");
    }
    Statement remove(db.get(), "DELETE FROM jobs WHERE id = ?1");  // Cascades.
    remove.Bind(1, id).Run();
    transaction.Commit();
    return *state;
  });
}

Result<std::optional<Job>> SqliteJobStore::ClaimNextJob(std::string_view worker_id,
                                                        std::chrono::milliseconds lease) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (Status s = CheckLease(lease); !s.ok()) return s;
  return Run("claim a job", [&](SqliteConnection& db) -> Result<std::optional<Job>> {
    // One write transaction for the sweep and the claim: no other thread or process can claim
    // between our choosing the oldest queued job and marking it running.
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    SweepLocked(db, now);
    std::optional<Job> job;
    {
      static const std::string kSql =
          Sql({"UPDATE jobs SET state = 'running', lease_owner = ?1, lease_until = ?2, "
               "started_at = ?3, updated_at = ?3 WHERE id = (SELECT id FROM jobs WHERE "
               "state = 'queued' ORDER BY queued_at, rowid LIMIT 1) RETURNING ",
               kJobColumns});
      Statement claim(db.get(), kSql);
      claim.Bind(1, worker_id).Bind(2, now + lease.count()).Bind(3, now);
      if (claim.Step()) {
        job = ReadJob(claim);
        claim.Run();  // A write statement must finish before COMMIT.
      }
    }
    if (job) {
      std::string message = "started by worker " + Quote(worker_id) + " (run " +
                            std::to_string(job->attempts + 1) + " of at most " +
                            std::to_string(job->max_attempts) + ")";
      if (!job->finished_stages.empty()) {
        message += "; resuming after stage " + Quote(job->finished_stages.back());
      }
      InsertEvent(db, job->id, now, "", LogLevel::kInfo, message, job->progress);
    }
    transaction.Commit();
    return job;
  });
}

Result<HeartbeatReply> SqliteJobStore::Heartbeat(std::string_view job_id,
                                                 std::string_view worker_id,
                                                 std::chrono::milliseconds lease) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (Status s = CheckLease(lease); !s.ok()) return s;
  if (!IsValidJobId(job_id)) return HeartbeatReply{};
  return Run("heartbeat", [&](SqliteConnection& db) -> Result<HeartbeatReply> {
    const std::int64_t now = Now();
    // One autocommit statement: it takes the write lock before reading, like BEGIN IMMEDIATE.
    Statement update(db.get(),
                     "UPDATE jobs SET lease_until = ?3, updated_at = ?4 "
                     "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2 "
                     "RETURNING cancel_requested, lease_until");
    update.Bind(1, job_id).Bind(2, worker_id).Bind(3, now + lease.count()).Bind(4, now);
    HeartbeatReply reply;
    if (update.Step()) {
      reply.owned = true;
      reply.cancel_requested = update.Int64(0) != 0;
      reply.lease_until_ms = update.Int64(1);
      update.Run();
    }
    return reply;
  });
}

Status SqliteJobStore::RecordProgress(std::string_view job_id,
                                      std::string_view worker_id,
                                      const JobProgressUpdate& update) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  if (std::isnan(update.progress)) return Status::InvalidArgument("progress is NaN");
  return Run("record progress", [&](SqliteConnection& db) -> Status {
    Result<std::string> stage_patch = PatchText(update.stage_progress, "stage_progress");
    if (!stage_patch.ok()) return stage_patch.status();
    Result<std::string> counts_patch = PatchText(update.counts.ToJson(), "counts");
    if (!counts_patch.ok()) return counts_patch.status();
    Statement statement(db.get(),
                        "UPDATE jobs SET stage = coalesce(?3, stage), progress = ?4, "
                        "stage_progress = json_patch(stage_progress, ?5), "
                        "counts = json_patch(counts, ?6), updated_at = ?7 "
                        "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2");
    statement.BindTextOrNull(3, update.stage).Bind(4, std::clamp(update.progress, 0.0, 1.0));
    statement.Bind(5, *stage_patch).Bind(6, *counts_patch).Bind(7, Now());
    return RunOwnedUpdate(db, statement, job_id, worker_id);
  });
}

Status SqliteJobStore::MarkStageFinished(std::string_view job_id,
                                         std::string_view worker_id,
                                         std::string_view stage,
                                         double seconds) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  if (stage.empty()) return Status::InvalidArgument("stage name must not be empty");
  if (!std::isfinite(seconds) || seconds < 0) {
    return Status::InvalidArgument("stage seconds must be finite and >= 0");
  }
  return Run("mark stage finished", [&](SqliteConnection& db) -> Status {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    json patch = json::object();
    patch[std::string(stage)] = {{"progress", 1.0}, {"seconds", seconds}, {"finished_at", now}};
    Statement update(db.get(),
                     "UPDATE jobs SET finished_stages = CASE WHEN EXISTS (SELECT 1 FROM "
                     "json_each(jobs.finished_stages) WHERE json_each.value = ?3) "
                     "THEN finished_stages ELSE json_insert(finished_stages, '$[#]', ?3) END, "
                     "stage_progress = json_patch(stage_progress, ?4), updated_at = ?5 "
                     "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2");
    update.Bind(3, stage).Bind(4, DumpJson(patch)).Bind(5, now);
    if (Status s = RunOwnedUpdate(db, update, job_id, worker_id); !s.ok()) return s;
    InsertEvent(db, job_id, now, stage, LogLevel::kInfo,
                "stage " + Quote(stage) + " finished in " + FormatSeconds(seconds), std::nullopt);
    transaction.Commit();
    return Status::Ok();
  });
}

Result<std::vector<std::string>> SqliteJobStore::ListFinishedStages(std::string_view job_id) {
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  return Run("list finished stages", [&](SqliteConnection& db) -> Result<std::vector<std::string>> {
    Statement select(db.get(), "SELECT finished_stages FROM jobs WHERE id = ?1");
    select.Bind(1, job_id);
    if (!select.Step()) return JobNotFound(job_id);
    return ParseStageList(select.Text(0));
  });
}

Status SqliteJobStore::FinishOwned(std::string_view what,
                                   std::string_view job_id,
                                   std::string_view worker_id,
                                   const std::function<void(Statement&, std::int64_t)>& bind,
                                   std::string_view sql,
                                   LogLevel level,
                                   const std::string& event_stage,
                                   const std::string& event_message) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  return Run(what, [&](SqliteConnection& db) -> Status {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    Statement update(db.get(), sql);
    bind(update, now);
    if (Status s = RunOwnedUpdate(db, update, job_id, worker_id); !s.ok()) return s;
    InsertEvent(db, job_id, now, event_stage, level, event_message, std::nullopt);
    transaction.Commit();
    return Status::Ok();
  });
}

Status SqliteJobStore::FinishSucceeded(std::string_view job_id,
                                       std::string_view worker_id,
                                       const JobOutput& output) {
  if (!IsSha256Hex(output.result_sha256)) {
    return Status::InvalidArgument("result_sha256 must be 64 lower-case hex digits");
  }
  if (output.result_bytes < 0) return Status::InvalidArgument("result_bytes must be >= 0");
  Result<std::string> counts = PatchText(output.counts.ToJson(), "counts");
  if (!counts.ok()) return counts.status();
  return FinishOwned(
      "finish job", job_id, worker_id,
      [&](Statement& update, std::int64_t now) {
        update.Bind(3, now).Bind(4, output.result_bytes).Bind(5, output.result_sha256);
        update.Bind(6, *counts);
      },
      "UPDATE jobs SET state = 'succeeded', progress = 1, finished_at = ?3, updated_at = ?3, "
      "lease_owner = NULL, lease_until = NULL, error = NULL, error_stage = NULL, "
      "result_bytes = ?4, result_sha256 = ?5, counts = json_patch(counts, ?6) "
      "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2",
      LogLevel::kInfo, "", "succeeded");
}

Status SqliteJobStore::FinishFailed(std::string_view job_id,
                                    std::string_view worker_id,
                                    std::string_view error,
                                    std::string_view stage) {
  if (error.empty()) return Status::InvalidArgument("a failed job needs an error message");
  return FinishOwned(
      "fail job", job_id, worker_id,
      [&](Statement& update, std::int64_t now) {
        update.Bind(3, now).Bind(4, error).BindTextOrNull(5, stage);
      },
      "UPDATE jobs SET state = 'failed', finished_at = ?3, updated_at = ?3, "
      "lease_owner = NULL, lease_until = NULL, error = ?4, error_stage = ?5 "
      "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2",
      LogLevel::kError, std::string(stage), "failed: " + std::string(error));
}

Status SqliteJobStore::FinishCanceled(std::string_view job_id, std::string_view worker_id) {
  return FinishOwned(
      "cancel job", job_id, worker_id,
      [&](Statement& update, std::int64_t now) { update.Bind(3, now); },
      "UPDATE jobs SET state = 'canceled', finished_at = ?3, updated_at = ?3, "
      "lease_owner = NULL, lease_until = NULL "
      "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2",
      LogLevel::kInfo, "", "canceled");
}

Result<JobState> SqliteJobStore::ReleaseJob(std::string_view job_id, std::string_view worker_id) {
  if (Status s = CheckWorker(worker_id); !s.ok()) return s;
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  return Run("release job", [&](SqliteConnection& db) -> Result<JobState> {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const std::int64_t now = Now();
    std::optional<JobState> state;
    {
      Statement update(
          db.get(),
          "UPDATE jobs SET state = CASE WHEN cancel_requested THEN 'canceled' ELSE 'queued' END, "
          "finished_at = CASE WHEN cancel_requested THEN ?3 END, updated_at = ?3, "
          "lease_owner = NULL, lease_until = NULL "
          "WHERE id = ?1 AND state = 'running' AND lease_owner = ?2 RETURNING state");
      update.Bind(1, job_id).Bind(2, worker_id).Bind(3, now);
      if (update.Step()) {
        state = ParseJobState(update.Text(0));
        update.Run();
      }
    }
    if (!state) return OwnershipError(db, job_id, worker_id);
    InsertEvent(db, job_id, now, "", LogLevel::kInfo,
                "released by worker " + Quote(worker_id) +
                    (*state == JobState::kQueued ? "; back in the queue" : "; canceled"),
                std::nullopt);
    transaction.Commit();
    return *state;
  });
}

Result<std::int64_t> SqliteJobStore::AppendEvent(std::string_view job_id, const NewEvent& event) {
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  if (event.progress && !(*event.progress >= 0.0 && *event.progress <= 1.0)) {
    return Status::InvalidArgument("event progress must be in [0, 1]");
  }
  return Run("append event", [&](SqliteConnection& db) -> Result<std::int64_t> {
    // INSERT ... SELECT ... WHERE EXISTS: a missing job is a miss, not a foreign-key error.
    Statement insert(
        db.get(),
        "INSERT INTO job_events (job_id, time, stage, level, message, progress) "
        "SELECT ?1, ?2, ?3, ?4, ?5, ?6 WHERE EXISTS (SELECT 1 FROM jobs WHERE id = ?1) "
        "RETURNING id");
    insert.Bind(1, job_id).Bind(2, Now()).BindTextOrNull(3, event.stage);
    insert.Bind(4, EventLevelName(event.level)).Bind(5, event.message).Bind(6, event.progress);
    if (!insert.Step()) return JobNotFound(job_id);
    const std::int64_t id = insert.Int64(0);
    insert.Run();
    return id;
  });
}

Result<std::vector<JobEvent>> SqliteJobStore::ListEvents(std::string_view job_id,
                                                         std::int64_t after_id,
                                                         int limit) {
  if (!IsValidJobId(job_id)) return JobNotFound(job_id);
  if (limit < 1 || limit > kMaxPageSize) {
    return Status::InvalidArgument("limit must be in [1, " + std::to_string(kMaxPageSize) + "]");
  }
  return Run("list events", [&](SqliteConnection& db) -> Result<std::vector<JobEvent>> {
    Transaction transaction(db, Transaction::Mode::kDeferred);
    if (!FindJobState(db, job_id)) return JobNotFound(job_id);
    Statement select(db.get(),
                     "SELECT id, time, stage, level, message, progress FROM job_events "
                     "WHERE job_id = ?1 AND id > ?2 ORDER BY id LIMIT ?3");
    select.Bind(1, job_id).Bind(2, after_id).Bind(3, limit);
    std::vector<JobEvent> events;
    while (select.Step()) {
      JobEvent event;
      event.id = select.Int64(0);
      event.job_id = std::string(job_id);
      event.time_ms = select.Int64(1);
      event.stage = select.Text(2);
      event.level = ParseEventLevel(select.Text(3));
      event.message = select.Text(4);
      event.progress = select.OptionalDouble(5);
      events.push_back(std::move(event));
    }
    return events;
  });
}

Result<QueueStats> SqliteJobStore::GetQueueStats() {
  return Run("read queue statistics", [&](SqliteConnection& db) -> Result<QueueStats> {
    Transaction transaction(db, Transaction::Mode::kDeferred);
    QueueStats stats;
    {
      Statement select(db.get(), "SELECT state, count(*) FROM jobs GROUP BY state");
      while (select.Step()) {
        if (const std::optional<JobState> state = ParseJobState(select.Text(0))) {
          stats.jobs_by_state[static_cast<int>(*state)] = select.Int64(1);
        }
      }
    }
    Statement oldest(db.get(), "SELECT min(queued_at) FROM jobs WHERE state = 'queued'");
    if (oldest.Step()) stats.oldest_queued_at_ms = oldest.OptionalInt64(0);
    return stats;
  });
}

Result<SweepResult> SqliteJobStore::SweepExpiredLeases() {
  return Run("sweep expired leases", [&](SqliteConnection& db) -> Result<SweepResult> {
    Transaction transaction(db, Transaction::Mode::kImmediate);
    const SweepResult result = SweepLocked(db, Now());
    transaction.Commit();
    return result;
  });
}

// ApplyMigrations, retried while the database is busy for up to another busy timeout. It takes
// the write lock (BEGIN IMMEDIATE) even when there is nothing to migrate; when many processes
// open the file at once on a loaded machine, SQLite's own busy wait can run out (seen twice in
// JobStoreConcurrency.ProcessesClaimEachJobOnceWithoutBusyErrors under the sanitizers while
// the machine ran a reconstruction).
Status ApplyMigrationsWhenFree(SqliteConnection& db, const SqliteJobStoreOptions& options) {
  std::optional<std::chrono::steady_clock::time_point> deadline;  // From the first busy failure.
  for (;;) {
    Status status = Status::Ok();
    try {
      status = ApplyMigrations(db, EmbeddedMigrations());
    } catch (const SqliteError& e) {
      status = e.status();
    }
    // Only a busy database is worth waiting for; a read-only one stays read-only.
    if (status.code() != StatusCode::kResourceExhausted ||
        sqlite3_db_readonly(db.get(), "main") == 1) {
      return status;
    }
    const auto now = std::chrono::steady_clock::now();
    if (!deadline) deadline = now + std::chrono::milliseconds(options.busy_timeout_ms);
    if (now > *deadline) return status;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

}  // namespace

Result<std::unique_ptr<JobStore>> OpenSqliteJobStore(const std::string& path,
                                                     const SqliteJobStoreOptions& options) {
  if (path.empty() || path == ":memory:" || path.starts_with("file:")) {
    return Status::InvalidArgument("the job database must be a file path, got " + Quote(path));
  }
  if (options.busy_timeout_ms < 0) {
    return Status::InvalidArgument("busy_timeout_ms must not be negative");
  }
  const std::string context = "open job database '" + path + "'";
  try {
    SqliteConnection db = SqliteConnection::Open(path);
    ConfigureConnection(db, options);
    // Migrations first: a file that belongs to another program or a newer Reconduit is refused
    // before anything (even the journal mode) is changed in it.
    if (Status s = ApplyMigrationsWhenFree(db, options); !s.ok()) {
      return Status(s.code(), context + ": " + s.message());
    }
    EnableWal(db, options);
    // SQLite opens a file it cannot write read-only without saying so; every change would then
    // fail (kResourceExhausted, "read-only"). Said once here, so an operator sees it at start.
    if (sqlite3_db_readonly(db.get(), "main") == 1) {
      LOG_WARNING << "the job database '" << path
                  << "' is read-only: jobs can be read, but uploads and every other change are "
                     "refused until it is writable (check the file's permissions and its "
                     "filesystem)";
    }
    return std::unique_ptr<JobStore>(
        std::make_unique<SqliteJobStore>(path, options, std::move(db)));
  } catch (const SqliteError& e) {
    return Status(e.status().code(), context + ": " + e.status().message());
  }
}

}  // namespace reconduit
