// Runs stages in order, resuming after the last finished one.
//
// For each stage the runner: skips it when work/<stage>/stage.json says it succeeded earlier
// with the same values of the options it uses (resume after a crash or restart); otherwise empties
// work/<stage>/, runs it with a Progress that feeds the overall figure, turns CanceledError into
// kCanceled and any other exception into kFailed with its message, records time and peak memory,
// and writes stage.json atomically on success. It stops at the first stage that does not succeed
// and checks the cancel token between stages. Nothing here knows about databases or HTTP.
#ifndef RECONDUIT_CORE_PIPELINE_RUNNER_H_
#define RECONDUIT_CORE_PIPELINE_RUNNER_H_

#include "core/pipeline/stage.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace reconduit {

struct PipelineCallbacks {
  // A stage begins (also called for resumed stages, with resumed = true afterwards).
  std::function<void(const Stage& stage)> on_stage_start;
  // Progress inside a stage; `overall` is the whole run's fraction in [0, 1].
  std::function<void(const Stage& stage, const ProgressUpdate& update, double overall)> on_progress;
  // A stage ended, whatever its status.
  std::function<void(const Stage& stage, const StageRecord& record)> on_stage_end;
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

// The finished stages recorded in a work folder that RunPipeline with `options` would resume
// (for status pages and tests).
std::vector<StageRecord> ReadFinishedStages(const Workspace& workspace,
                                            const std::vector<std::unique_ptr<Stage>>& stages,
                                            const PipelineOptions& options);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_RUNNER_H_
