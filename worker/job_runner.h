// Runs one claimed job from start to a final state: the worker's half of the job lifecycle.
//
// For a job this worker has claimed (JobStore::ClaimNextJob), Run():
//   1. parses the job's options (invalid -> failed, naming the field) and builds the run's
//      inputs from the store's photo records: accepted photos only, stored under generated
//      names in <data>/jobs/<id>/input/, shown and exported under their uploaded names;
//   2. keeps the lease: a heartbeat thread renews it every `heartbeat_interval` (lease / 3 by
//      default) whatever the stage is doing, and the cancel token's probe heart-beats when a
//      stage polls it (at most once per `cancel_check_interval`), so a cancel request reaches
//      the stage within about that interval;
//   3. removes from output/ the half-written files of an interrupted earlier run (temporary
//      files of atomic writes, which packaging would otherwise deliver), then
//      runs the pipeline (RunJobPipeline over core RunPipeline), resuming after the stages
//      whose work/<stage>/stage.json markers say they finished, and mirrors it into the store:
//      stage and progress (throttled), per-stage progress, time and memory, counts,
//      MarkStageFinished for each resumable stage whose output is complete (also for stages
//      resumed from disk that the store had not recorded, e.g. after a crash between the
//      marker and the store write), and events for stage starts and ends and the job's log
//      lines (rate-limited);
//   4. finishes the job: succeeded with result.zip's size and SHA-256 (the packaging stage's
//      PackageResult) and the counts; failed with the stage and the message; canceled when a
//      client asked; released back to the queue when the worker is stopping (RequestStop);
//      nothing at all when the lease was lost, since another worker may own the job by then.
//
// A failing or throwing job never escapes Run(): every exception becomes a failed job.
//
// Logging: while a job runs, Run() replaces the process-wide log sink (SetLogSink) with one
// that forwards every line to the previous sink (by default core/util's, so the line layout is
// the process's one) with the job id at the head of the message, and records it as a job event
// (rate-limited). A process therefore runs one job at a time; this is the worker's model (one
// job per process, several processes side by side).
#ifndef RECONDUIT_WORKER_JOB_RUNNER_H_
#define RECONDUIT_WORKER_JOB_RUNNER_H_

#include "core/util/cancel.h"
#include "core/util/status.h"
#include "worker/pipeline_driver.h"
#include "worker/progress_sink.h"

#include <nlohmann/json.hpp>

#include "store/data_layout.h"
#include "store/job_store.h"
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

struct JobRunnerOptions {
  // The data folder shared with the server (store/data_layout.h).
  std::filesystem::path data_dir = "data";
  // This worker's id as given to ClaimNextJob; must not be empty.
  std::string worker_id;
  // The lease each heartbeat extends to. A minute survives a stalled disk or a long GC-like
  // pause of the machine, and a dead worker's job is requeued a minute after its last beat.
  std::chrono::milliseconds lease{60'000};
  // Interval of the heartbeat thread; 0 = lease / 3, so two beats can be missed in a row
  // before the lease runs out.
  std::chrono::milliseconds heartbeat_interval{0};
  // Minimum interval of the cancel token's probe (one Heartbeat call each); the latency of a
  // cancel request when stages poll the token often. 1 s is one cheap write per second.
  std::chrono::milliseconds cancel_check_interval{1'000};
  // Throttling of progress writes and log-line events.
  ProgressSinkOptions sink;
  // The most threads a job may use (0 = all cores), also what jobs get whose options do not set
  // num_threads (or set 0). A job may ask for fewer, never more: a client cannot take more of
  // the machine than the operator allows. Lets an operator run several workers on one machine
  // without each using every core.
  int default_num_threads = 0;
  // The most resident memory a job may hold, in bytes (worker/memory_budget.h); 0 = no limit.
  // Over it, the running stage is canceled and the job fails with a message naming the stage;
  // the worker takes the next job. reconduit-worker's default: DefaultMemoryBudgetBytes().
  std::int64_t memory_budget_bytes = 0;
  // How often the resident memory is sampled against the budget.
  std::chrono::milliseconds memory_check_interval{100};
  // The stages to run; empty for CreatePipelineStages() (the full pipeline).
  StageListFactory make_stages;
  // Test hook for crash-safety tests (reconduit-worker's RECONDUIT_WORKER_CRASH_AT): called
  // on the thread running the job at these moments of a run, named:
  //   "stage-started:<stage>"  the store has heard of the stage's start; it has not run yet
  //   "stage-done:<stage>"     the stage succeeded and its work/<stage>/stage.json marker is on
  //                            disk; the store has not recorded it yet ("stage-done:package":
  //                            result.zip is in place)
  //   "before-finish"          result.zip is checked; FinishSucceeded comes next
  // Empty: none.
  std::function<void(const std::string& moment)> on_moment;

  // False, with a message naming the field, for invalid values.
  bool Check(std::string* error) const;
};

// How Run() left the job.
enum class JobRunOutcome {
  kSucceeded,  // FinishSucceeded.
  kFailed,     // FinishFailed (invalid options, a stage failed or threw, no result).
  kCanceled,   // A client's cancel was honoured (FinishCanceled).
  kReleased,   // RequestStop(): back in the queue (or canceled if a cancel was pending).
  kLeaseLost,  // The job stopped being ours; left alone.
  kStoreError  // The final store write kept failing; the lease will expire and requeue it.
};
std::string_view JobRunOutcomeName(JobRunOutcome outcome);

struct JobRunReport {
  JobRunOutcome outcome = JobRunOutcome::kFailed;
  // For kFailed: the stage (may be empty) and the message written to the job.
  std::string stage;
  std::string message;
  // Stages skipped because an earlier run finished them, and stages run now, in order.
  std::vector<std::string> resumed_stages;
  std::vector<std::string> run_stages;
  double seconds = 0.0;
};

// The run's inputs from the job's photo records: accepted photos in upload order, their files
// under `input_dir`. Display names are the uploaded names reduced to their last path
// component (never a path) and made unique ("a.jpg", "a (2).jpg"); an empty name falls back
// to the stored name. kInvalidArgument for a stored name that is not a plain file name (the
// store refuses those already) or when no photo is accepted.
Result<std::vector<InputImage>> PhotosFromRecords(const std::vector<JobImageRecord>& records,
                                                  const std::filesystem::path& input_dir);

// The counts a successful stage contributes to Job::counts: its summary's figures under their
// JobCounts names (ingest's "accepted" becomes images, matching's "pairs" matched_pairs, ...;
// registered, points, faces and models from any stage) and, for packaging, the number of
// files of its archive. Empty for a stage that did not succeed or has none.
JobCounts CountsOfStage(const StageRecord& record);

// The threads a job runs with: what its options ask for (`requested`, 0 = as many as allowed),
// never more than the worker's limit (`worker_limit`, 0 = the machine's cores).
int JobThreads(int requested, int worker_limit);

class JobRunner {
 public:
  // Does NOT take ownership of `store`, which must outlive the runner. Throws CheckError for
  // invalid options.
  JobRunner(JobStore& store, JobRunnerOptions options);
  JobRunner(const JobRunner&) = delete;
  JobRunner& operator=(const JobRunner&) = delete;

  // Runs `job`, which options.worker_id must have claimed, to a final state (see the file
  // comment). Never throws. Not reentrant: one job at a time per runner (and per process,
  // because of the log sink).
  JobRunReport Run(const Job& job);

  // Asks the running job (and any later Run) to stop and be released back to the queue, where
  // it resumes on the next worker. Returns at once; Run() returns once the stage notices the
  // cancel token. Thread-safe; async-signal-unsafe (call it from a normal thread).
  void RequestStop();

  // Gives the running job back to the queue right now, without waiting for its stage (for a
  // forced exit after RequestStop did not end the job in time). The caller must exit the
  // process immediately afterwards: the stage may still be writing into the job's folder,
  // and the next run of the job starts that stage over. Thread-safe. @return the store's
  // answer; kNotFound when no job is running.
  Status ReleaseRunningJobNow();

  // The id of the job Run() is working on, empty when idle. Thread-safe.
  std::string running_job_id() const;

 private:
  JobStore& store_;
  const JobRunnerOptions options_;
  const DataLayout layout_;
  std::atomic<bool> stop_requested_{false};

  // Guards the running job's id and token.
  mutable std::mutex running_mutex_;
  std::string running_job_id_;
  CancelToken running_cancel_;
};

}  // namespace reconduit

#endif  // RECONDUIT_WORKER_JOB_RUNNER_H_
