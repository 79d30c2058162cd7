#include "worker/pipeline_driver.h"

#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/pipeline/stage.h"
#include "core/util/timer.h"

#include <exception>
#include <string_view>
#include <utility>

namespace reconduit {
namespace {

StageOutcome ToOutcome(const StageRecord& record, bool resumable) {
  StageOutcome outcome;
  outcome.name = record.name;
  outcome.status = std::string(StageStatusName(record.status));
  outcome.success = record.status == StageStatus::kSuccess;
  outcome.resumable = resumable;
  outcome.resumed = record.resumed;
  outcome.message = record.message;
  outcome.seconds = record.seconds;
  outcome.peak_memory_bytes = record.peak_memory_bytes;
  outcome.summary = record.summary;
  return outcome;
}

PipelineOutcome Failure(std::string stage, std::string message, double seconds) {
  PipelineOutcome outcome;
  outcome.status = PipelineOutcomeStatus::kFailed;
  outcome.failed_stage = std::move(stage);
  outcome.message = std::move(message);
  outcome.seconds = seconds;
  return outcome;
}

}  // namespace

StageListFactory StagesUntil(std::string until) {
  return [until = std::move(until)] { return CreatePipelineStages(until); };
}

Status CheckUntilStage(const std::string& until) {
  const Result<StageList> stages = CreatePipelineStages(until);
  return stages.ok() ? Status::Ok() : stages.status();
}

PipelineOutcome RunJobPipeline(const PipelineJob& job,
                               const StageListFactory& make_stages,
                               const CancelToken& cancel,
                               const PipelineDriverCallbacks& callbacks) {
  const Timer timer;
  std::string current_stage;
  try {
    Result<StageList> created = make_stages ? make_stages() : CreatePipelineStages();
    if (!created.ok()) {
      return Failure("", "cannot set up the pipeline: " + created.status().message(), 0.0);
    }
    const StageList& stages = *created;
    if (stages.empty()) return Failure("", "the pipeline has no stages", 0.0);

    Workspace workspace;
    for (const JobPhoto& photo : job.photos) workspace.images.push_back({photo.path, photo.name});
    workspace.work_dir = job.work_dir;
    workspace.output_dir = job.output_dir;
    workspace.archive_path = job.archive_path;

    // The plan: which stages the runner will skip. ReadFinishedStages applies the runner's own
    // rule (a stage resumes only if every stage before it does), so the plan cannot disagree
    // with what RunPipeline then does.
    const std::vector<StageRecord> on_disk = ReadFinishedStages(workspace, stages, job.options);
    std::vector<StagePlan> plan;
    double total_weight = 0.0;
    for (std::size_t i = 0; i < stages.size(); ++i) {
      StagePlan entry;
      entry.name = std::string(stages[i]->Name());
      entry.title = std::string(stages[i]->Title());
      entry.weight = stages[i]->Weight();
      entry.resumable = stages[i]->Resumable();
      entry.finished_on_disk = i < on_disk.size();
      total_weight += entry.weight;
      plan.push_back(std::move(entry));
    }
    if (callbacks.on_plan) callbacks.on_plan(plan);

    auto index_of = [&](const Stage& stage) {
      for (std::size_t i = 0; i < stages.size(); ++i) {
        if (stages[i].get() == &stage) return i;
      }
      THROW_CHECK(false) << "unknown stage " << stage.Name();
      return std::size_t{0};
    };
    // Overall progress at the start of stage i (the runner gives the figure only inside a
    // stage; starts and ends of resumed stages need it too).
    auto weight_before = [&](std::size_t index) {
      double done = 0.0;
      for (std::size_t i = 0; i < index; ++i) done += plan[i].weight;
      return total_weight > 0 ? done / total_weight : 0.0;
    };

    PipelineCallbacks pipeline_callbacks;
    pipeline_callbacks.on_stage_start = [&](const Stage& stage) {
      const std::size_t i = index_of(stage);
      current_stage = plan[i].name;
      if (callbacks.on_stage_start) callbacks.on_stage_start(plan[i], weight_before(i));
    };
    pipeline_callbacks.on_progress = [&](const Stage& stage, const ProgressUpdate& update,
                                         double overall) {
      if (!callbacks.on_progress) return;
      const std::size_t i = index_of(stage);
      callbacks.on_progress(plan[i], update.fraction, update.done, update.total, update.message,
                            overall);
    };
    pipeline_callbacks.on_stage_end = [&](const Stage& stage, const StageRecord& record) {
      const std::size_t i = index_of(stage);
      if (!callbacks.on_stage_end) return;
      const double overall =
          record.status == StageStatus::kSuccess ? weight_before(i + 1) : weight_before(i);
      callbacks.on_stage_end(ToOutcome(record, plan[i].resumable), overall);
    };

    const PipelineResult result =
        RunPipeline(stages, workspace, job.options, cancel, pipeline_callbacks);
    PipelineOutcome outcome;
    switch (result.status) {
      case StageStatus::kSuccess:
        outcome.status = PipelineOutcomeStatus::kSuccess;
        break;
      case StageStatus::kCanceled:
        outcome.status = PipelineOutcomeStatus::kCanceled;
        break;
      case StageStatus::kFailed:
      case StageStatus::kDegenerate:
        outcome.status = PipelineOutcomeStatus::kFailed;
        break;
    }
    outcome.failed_stage = result.failed_stage;
    outcome.message = result.message;
    for (const StageRecord& record : result.stages) {
      bool resumable = true;
      for (const StagePlan& entry : plan) {
        if (entry.name == record.name) resumable = entry.resumable;
      }
      outcome.stages.push_back(ToOutcome(record, resumable));
    }
    outcome.seconds = timer.ElapsedSeconds();
    return outcome;
  } catch (const std::exception& e) {
    // RunPipeline catches what stages throw; this is the rest (the factory, a callback run
    // outside a stage, a violated precondition).
    return Failure(current_stage, e.what(), timer.ElapsedSeconds());
  } catch (...) {
    return Failure(current_stage, "unknown exception", timer.ElapsedSeconds());
  }
}

}  // namespace reconduit
