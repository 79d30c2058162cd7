// How the worker runs core/pipeline for one job: which stages, and a RunPipeline that never
// throws.
//
// The worker uses core/pipeline's own types (Workspace, PipelineCallbacks, PipelineResult,
// StageRecord); this file adds only what a long-lived process needs on top: a replaceable
// stage list (tests substitute their own) and a run from which no exception escapes.
#ifndef RECONDUIT_WORKER_PIPELINE_DRIVER_H_
#define RECONDUIT_WORKER_PIPELINE_DRIVER_H_

#include "core/pipeline/runner.h"
#include "core/pipeline/stage.h"
#include "core/util/status.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace reconduit {

using StageList = std::vector<std::unique_ptr<Stage>>;
// Makes the stages a job runs, in order (the last one writes result.zip). The default is
// CreatePipelineStages(); tests substitute their own.
using StageListFactory = std::function<Result<StageList>()>;

// The pipeline's stages up to and including `until` (empty: all), then packaging: a factory
// over CreatePipelineStages(until). An unknown name makes the factory fail.
StageListFactory StagesUntil(std::string until);

// Ok when `until` is empty or names a pipeline stage; otherwise kInvalidArgument listing the
// stages.
Status CheckUntilStage(const std::string& until);

// RunPipeline over the stages `make_stages` returns. Never throws: a factory error, an empty
// stage list or an exception anywhere (a callback outside a stage, a violated precondition)
// becomes a kFailed result with the message and the stage it came from, if any. An exception
// thrown by a callback inside a stage (on_progress) fails that stage, as any stage exception
// does.
// @param make_stages  empty for CreatePipelineStages().
PipelineResult RunJobPipeline(const Workspace& workspace,
                              const PipelineOptions& options,
                              const StageListFactory& make_stages,
                              const CancelToken& cancel,
                              const PipelineCallbacks& callbacks);

}  // namespace reconduit

#endif  // RECONDUIT_WORKER_PIPELINE_DRIVER_H_
