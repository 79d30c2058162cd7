#include "worker/pipeline_driver.h"

#include "core/pipeline/default_stages.h"
#include "core/util/timer.h"

#include <exception>
#include <utility>

namespace reconduit {
namespace {

PipelineResult Failure(std::string stage, std::string message, double seconds) {
  PipelineResult result;
  result.status = StageStatus::kFailed;
  result.failed_stage = std::move(stage);
  result.message = std::move(message);
  result.seconds = seconds;
  return result;
}

}  // namespace

StageListFactory StagesUntil(std::string until) {
  return [until = std::move(until)] { return CreatePipelineStages(until); };
}

Status CheckUntilStage(const std::string& until) {
  const Result<StageList> stages = CreatePipelineStages(until);
  return stages.ok() ? Status::Ok() : stages.status();
}

PipelineResult RunJobPipeline(const Workspace& workspace,
                              const PipelineOptions& options,
                              const StageListFactory& make_stages,
                              const CancelToken& cancel,
                              const PipelineCallbacks& callbacks) {
  const Timer timer;
  // The stage a callback exception comes from: the last one that started.
  std::string current_stage;
  PipelineCallbacks tracking = callbacks;
  tracking.on_stage_start = [&](const Stage& stage, double overall) {
    current_stage = std::string(stage.Name());
    if (callbacks.on_stage_start) callbacks.on_stage_start(stage, overall);
  };
  try {
    Result<StageList> stages = make_stages ? make_stages() : CreatePipelineStages();
    if (!stages.ok()) {
      return Failure("", "cannot set up the pipeline: " + stages.status().message(), 0.0);
    }
    if (stages->empty()) return Failure("", "the pipeline has no stages", 0.0);
    return RunPipeline(*stages, workspace, options, cancel, tracking);
  } catch (const std::exception& e) {
    // RunPipeline catches what stages throw; this is the rest.
    return Failure(current_stage, e.what(), timer.ElapsedSeconds());
  } catch (...) {
    return Failure(current_stage, "unknown exception", timer.ElapsedSeconds());
  }
}

}  // namespace reconduit
