// Runs stages in order, resuming after the last finished one.
//
// Before the first stage the runner announces the plan (which stages it will resume). For each
// stage it: skips it when work/<stage>/stage.json says it succeeded earlier with the same values
// of the options it uses (resume after a crash or restart); otherwise empties work/<stage>/
// (unless the stage keeps finished parts, Stage::KeepsFinishedParts),
// runs it with a Progress that feeds the overall figure, turns CanceledError into
// kCanceled and any other exception into kFailed with its message, records time and peak memory
// (the stage's own high-water mark, StagePeakMemory, and the process's), and writes stage.json
// atomically on success. It stops at the first stage that does not succeed
// and checks the cancel token between stages. Nothing here knows about databases or HTTP.
#ifndef RECONDUIT_CORE_PIPELINE_RUNNER_H_
#define RECONDUIT_CORE_PIPELINE_RUNNER_H_

#include "core/pipeline/stage.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace reconduit {

// A stage of a run as the runner announces it before the first stage (PlanPipeline).
struct StagePlan {
  std::string name;
  std::string title;
  double weight = 1.0;
  bool resumable = true;
  // Its work/<stage>/stage.json says it succeeded in an earlier run with the same option
  // values, and every stage before it resumes too: the run will skip it.
  bool finished_on_disk = false;
};

// Called on the thread that runs the pipeline, except on_progress, which a stage may call from
// its worker threads (never concurrently with itself). `overall` is the run's fraction in
// [0, 1], weighted by the stages' Weight(). An exception thrown by on_progress fails the stage
// it came from; one thrown by the others leaves RunPipeline.
struct PipelineCallbacks {
  // Once, before the first stage: the stages in order and which of them will be resumed.
  std::function<void(const std::vector<StagePlan>& plan)> on_plan;
  // A stage begins (also called for resumed stages, with resumed = true afterwards).
  std::function<void(const Stage& stage, double overall)> on_stage_start;
  // Progress inside a stage.
  std::function<void(const Stage& stage, const ProgressUpdate& update, double overall)> on_progress;
  // A stage ended, whatever its status (resumed stages too, with record.resumed).
  std::function<void(const Stage& stage, const StageRecord& record, double overall)> on_stage_end;
};

struct PipelineResult {
  StageStatus status = StageStatus::kFailed;
  std::string failed_stage;  // Empty on success.
  std::string message;
  std::vector<StageRecord> stages;  // Every stage that ran or was resumed, in order.
  double seconds = 0.0;
};

PipelineResult RunPipeline(const std::vector<std::unique_ptr<Stage>>& stages,
                           const Workspace& workspace,
                           const PipelineOptions& options,
                           const CancelToken& cancel,
                           const PipelineCallbacks& callbacks = {});

// What RunPipeline with `options` will do with each stage: resume it (finished_on_disk) or run
// it. Applies the runner's own rule (a stage resumes only if every stage before it does), so
// the plan cannot disagree with the run.
std::vector<StagePlan> PlanPipeline(const std::vector<std::unique_ptr<Stage>>& stages,
                                    const Workspace& workspace,
                                    const PipelineOptions& options);

// The finished stages recorded in a work folder that RunPipeline with `options` would resume
// (for status pages and tests).
std::vector<StageRecord> ReadFinishedStages(const Workspace& workspace,
                                            const std::vector<std::unique_ptr<Stage>>& stages,
                                            const PipelineOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_RUNNER_H_
