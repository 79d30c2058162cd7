// The worker's view of the reconstruction pipeline: runs core/pipeline's stages for one job and
// reports what happens in plain values.
//
// Why a separate layer: it keeps the two halves of the worker apart — job_runner.cc talks to
// the store and to this driver, pipeline_driver.cc to core/pipeline — so each can be tested
// with the other faked, and store code never depends on pipeline headers. Stage is only
// forward-declared here.
#ifndef RECONDUIT_WORKER_PIPELINE_DRIVER_H_
#define RECONDUIT_WORKER_PIPELINE_DRIVER_H_

#include "core/options/pipeline_options.h"
#include "core/util/cancel.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace reconduit {

class Stage;  // core/pipeline/stage.h

using StageList = std::vector<std::unique_ptr<Stage>>;
// Makes the stages a job runs, in order (the last one writes result.zip). The default is
// CreatePipelineStages(); tests substitute their own.
using StageListFactory = std::function<Result<StageList>()>;

// A photo of the job: where its bytes are and the name to show and export.
struct JobPhoto {
  std::filesystem::path path;
  std::string name;
};

// Everything a run reads and where it writes (a core Workspace plus options).
struct PipelineJob {
  std::vector<JobPhoto> photos;
  // work/<stage>/ folders with their stage.json markers.
  std::filesystem::path work_dir;
  // Deliverables, laid out as in result.zip.
  std::filesystem::path output_dir;
  // result.zip; the packaging stage writes it atomically.
  std::filesystem::path archive_path;
  PipelineOptions options;
};

// A stage of the run as the driver announces it before running.
struct StagePlan {
  std::string name;
  std::string title;
  double weight = 1.0;
  bool resumable = true;
  // Its work/<stage>/stage.json says it succeeded in an earlier run, and every stage before it
  // resumes too: the run will skip it.
  bool finished_on_disk = false;
};

// How a stage ended (core StageRecord in plain values).
struct StageOutcome {
  std::string name;
  // "success", "canceled", "failed" or "degenerate" (StageStatusName).
  std::string status;
  bool success = false;
  bool resumable = true;
  // Taken from an earlier run instead of run again.
  bool resumed = false;
  std::string message;
  double seconds = 0.0;
  // Process peak RSS when the stage ended (a worker process runs many jobs: this is a maximum
  // over its life so far, not the stage's own peak).
  std::int64_t peak_memory_bytes = 0;
  nlohmann::json summary = nlohmann::json::object();
};

enum class PipelineOutcomeStatus { kSuccess, kCanceled, kFailed };

struct PipelineOutcome {
  PipelineOutcomeStatus status = PipelineOutcomeStatus::kFailed;
  // The stage that did not succeed (may be empty for a failure before the first stage).
  std::string failed_stage;
  std::string message = "pipeline did not run";
  std::vector<StageOutcome> stages;
  double seconds = 0.0;
};

// Called on the thread that runs the pipeline, except on_progress, which a stage may call from
// its worker threads (never concurrently with itself). `overall` is the run's fraction in
// [0, 1], weighted by the stages' Weight().
struct PipelineDriverCallbacks {
  // Once, before the first stage: the stages in order.
  std::function<void(const std::vector<StagePlan>& plan)> on_plan;
  std::function<void(const StagePlan& stage, double overall)> on_stage_start;
  // `fraction` is the stage's own progress in [0, 1]; done/total in the stage's units.
  std::function<void(const StagePlan& stage,
                     double fraction,
                     std::size_t done,
                     std::size_t total,
                     const std::string& message,
                     double overall)>
      on_progress;
  std::function<void(const StageOutcome& outcome, double overall)> on_stage_end;
};

// The pipeline's stages up to and including `until` (empty: all), then packaging: a factory
// over CreatePipelineStages(until). An unknown name makes the factory fail.
StageListFactory StagesUntil(std::string until);

// Ok when `until` is empty or names a pipeline stage; otherwise kInvalidArgument listing the
// stages.
Status CheckUntilStage(const std::string& until);

// Runs the stages `make_stages` returns over `job`, resuming after the stages whose markers say
// they finished (core RunPipeline). Never throws: a factory error or an exception anywhere
// becomes a kFailed outcome with the message. Throws nothing out of the callbacks either: an
// exception thrown by a callback fails the stage it came from (as any stage exception does).
// @param make_stages  empty for CreatePipelineStages().
PipelineOutcome RunJobPipeline(const PipelineJob& job,
                               const StageListFactory& make_stages,
                               const CancelToken& cancel,
                               const PipelineDriverCallbacks& callbacks);

}  // namespace reconduit

#endif  // RECONDUIT_WORKER_PIPELINE_DRIVER_H_
