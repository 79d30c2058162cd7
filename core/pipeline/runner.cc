#include "core/pipeline/runner.h"

#include "core/io/file_util.h"
#include "core/util/logging.h"
#include "core/util/timer.h"

#include <exception>
#include <filesystem>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

constexpr char kMarker[] = "stage.json";
// The options an attempt of a KeepsFinishedParts() stage started with.
constexpr char kAttempt[] = "attempt.json";

// The values of the options `stage` depends on.
nlohmann::json UsedOptionValues(const Stage& stage, const PipelineOptions& options) {
  const nlohmann::json all = PipelineOptionsToJson(options);
  nlohmann::json used = nlohmann::json::object();
  for (const std::string& name : stage.OptionsUsed()) {
    THROW_CHECK(all.contains(name)) << "stage " << stage.Name() << " names unknown option " << name;
    used[name] = all.at(name);
  }
  return used;
}

// The record of `stage` when it finished in an earlier run with the same option values.
std::optional<StageRecord> ReadMarker(const Stage& stage,
                                      const fs::path& stage_dir,
                                      const PipelineOptions& options) {
  auto text = ReadFile(stage_dir / kMarker);
  if (!text.ok()) return std::nullopt;
  try {
    StageRecord record = StageRecord::FromJson(nlohmann::json::parse(*text));
    if (record.status != StageStatus::kSuccess) return std::nullopt;
    const nlohmann::json now = UsedOptionValues(stage, options);
    if (record.options != now) {
      LOG_INFO << "stage " << stage.Name() << ": options changed since the earlier run ("
               << record.options.dump() << " then, " << now.dump() << " now): running again";
      return std::nullopt;
    }
    return record;
  } catch (const nlohmann::json::exception& e) {
    LOG_WARNING << "ignoring unreadable " << (stage_dir / kMarker).string() << ": " << e.what();
  }
  return std::nullopt;
}

// Makes `stage_dir` ready for a run of `stage`: emptied (outputs of an interrupted earlier
// attempt), unless the stage keeps finished parts, `after_resumed` (every stage before it
// resumed) and the interrupted attempt used the same options (Stage::KeepsFinishedParts).
Status PrepareStageDir(const Stage& stage,
                       const fs::path& stage_dir,
                       const PipelineOptions& options,
                       bool after_resumed) {
  const nlohmann::json used = UsedOptionValues(stage, options);
  if (stage.KeepsFinishedParts() && after_resumed) {
    auto text = ReadFile(stage_dir / kAttempt);
    if (text.ok() && nlohmann::json::parse(*text, nullptr, false) == used) {
      LOG_INFO << "stage " << stage.Name() << ": keeping the parts an earlier attempt finished";
      return Status::Ok();
    }
  }
  std::error_code ec;
  fs::remove_all(stage_dir, ec);
  fs::create_directories(stage_dir, ec);
  if (ec) return Status::Internal("cannot create " + stage_dir.string() + ": " + ec.message());
  if (stage.KeepsFinishedParts()) return WriteFileAtomically(stage_dir / kAttempt, used.dump());
  return Status::Ok();
}

}  // namespace

std::vector<std::string> Stage::OptionsUsed() const {
  std::vector<std::string> names;
  for (const OptionSpec& spec : PipelineOptionSpecs()) {
    if (OptionAffectsResults(spec.name)) names.push_back(spec.name);
  }
  return names;
}

std::string_view StageStatusName(StageStatus status) {
  switch (status) {
    case StageStatus::kSuccess:
      return "success";
    case StageStatus::kCanceled:
      return "canceled";
    case StageStatus::kFailed:
      return "failed";
    case StageStatus::kDegenerate:
      return "degenerate";
  }
  return "unknown";
}

StageResult StageResult::Skipped(std::string_view stage,
                                 const std::string& reason,
                                 nlohmann::json summary) {
  LOG_WARNING << stage << ": skipped: " << reason;
  summary["skipped_reason"] = reason;
  return Success(std::move(summary));
}

nlohmann::json StageRecord::ToJson() const {
  return {{"name", name},
          {"status", StageStatusName(status)},
          {"message", message},
          {"seconds", seconds},
          {"peak_memory_bytes", peak_memory_bytes},
          {"stage_peak_memory_bytes", stage_peak_memory_bytes},
          {"stage_peak_memory_own", stage_peak_memory_own},
          {"summary", summary},
          {"options", options}};
}

StageRecord StageRecord::FromJson(const nlohmann::json& json) {
  StageRecord record;
  record.name = json.at("name").get<std::string>();
  const std::string status = json.at("status").get<std::string>();
  for (StageStatus s : {StageStatus::kSuccess, StageStatus::kCanceled, StageStatus::kFailed,
                        StageStatus::kDegenerate}) {
    if (StageStatusName(s) == status) record.status = s;
  }
  record.message = json.value("message", "");
  record.seconds = json.value("seconds", 0.0);
  record.peak_memory_bytes = json.value("peak_memory_bytes", std::int64_t{0});
  // Markers written before stages kept their own peak have neither: unknown, not the stage's.
  record.stage_peak_memory_bytes = json.value("stage_peak_memory_bytes", std::int64_t{0});
  record.stage_peak_memory_own = json.value("stage_peak_memory_own", false);
  record.summary = json.value("summary", nlohmann::json::object());
  // Markers written before options were recorded have none: they match no stage that uses
  // options, so such a stage runs again.
  record.options = json.value("options", nlohmann::json::object());
  return record;
}

std::vector<StageRecord> ReadFinishedStages(const Workspace& workspace,
                                            const std::vector<std::unique_ptr<Stage>>& stages,
                                            const PipelineOptions& options) {
  std::vector<StageRecord> records;
  for (const auto& stage : stages) {
    if (!stage->Resumable()) break;
    auto record = ReadMarker(*stage, workspace.StageDir(stage->Name()), options);
    if (!record) break;
    records.push_back(std::move(*record));
  }
  return records;
}

namespace {

// The plan of `stages` when the first `finished` of them resume.
std::vector<StagePlan> MakePlan(const std::vector<std::unique_ptr<Stage>>& stages,
                                std::size_t finished) {
  std::vector<StagePlan> plan;
  for (std::size_t i = 0; i < stages.size(); ++i) {
    plan.push_back({std::string(stages[i]->Name()), std::string(stages[i]->Title()),
                    stages[i]->Weight(), stages[i]->Resumable(), i < finished});
  }
  return plan;
}

// The run's overall fraction at each stage boundary: [i] when stage i starts, [i + 1] when it
// has succeeded (the stages' weights, normalised; all 0 when the weights add up to 0).
std::vector<double> StageBoundaries(const std::vector<StagePlan>& plan) {
  double total = 0.0;
  for (const StagePlan& stage : plan) total += stage.weight;
  std::vector<double> boundaries{0.0};
  double done = 0.0;
  for (const StagePlan& stage : plan) {
    done += stage.weight;
    boundaries.push_back(total > 0 ? done / total : 0.0);
  }
  return boundaries;
}

// Runs `stage` in its (fresh) folder: its exceptions become the record's status, time and peak
// memory (the stage's own and the process's) are recorded, and stage.json is written when it
// succeeded.
StageRecord RunStage(const Stage& stage, StageContext& context, const PipelineOptions& options) {
  const std::string name(stage.Name());
  LOG_INFO << "stage " << name << ": " << stage.Title();
  const Timer timer;
  const StagePeakMemory memory;
  StageRecord record;
  record.name = name;
  record.resumable = stage.Resumable();
  record.options = UsedOptionValues(stage, options);
  try {
    StageResult stage_result = stage.Run(context);
    record.status = stage_result.status;
    record.message = std::move(stage_result.message);
    record.summary = std::move(stage_result.summary);
    record.package = std::move(stage_result.package);
  } catch (const CanceledError&) {
    record.status = StageStatus::kCanceled;
    record.message = "canceled during stage " + name;
  } catch (const std::exception& e) {
    record.status = StageStatus::kFailed;
    record.message = e.what();
  }
  record.seconds = timer.ElapsedSeconds();
  record.stage_peak_memory_bytes = memory.PeakBytes();
  record.stage_peak_memory_own = memory.Own();
  record.peak_memory_bytes = PeakMemoryBytes();

  if (record.status == StageStatus::kSuccess) {
    context.progress.Finish();  // The overall figure reaches this stage's end even if throttled.
    const Status written =
        WriteFileAtomically(context.stage_dir / kMarker, record.ToJson().dump(2) + "\n");
    if (!written.ok()) {
      record.status = StageStatus::kFailed;
      record.message = "cannot record the end of the stage: " + written.message();
    }
  }
  LOG_INFO << "stage " << name << ": " << StageStatusName(record.status) << " in " << record.seconds
           << " s" << (record.message.empty() ? "" : ": ") << record.message;
  return record;
}

}  // namespace

std::vector<StagePlan> PlanPipeline(const std::vector<std::unique_ptr<Stage>>& stages,
                                    const Workspace& workspace,
                                    const PipelineOptions& options) {
  return MakePlan(stages, ReadFinishedStages(workspace, stages, options).size());
}

PipelineResult RunPipeline(const std::vector<std::unique_ptr<Stage>>& stages,
                           const Workspace& workspace,
                           const PipelineOptions& options,
                           const CancelToken& cancel,
                           const PipelineCallbacks& callbacks) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const Timer total_timer;
  PipelineResult result;
  auto finish = [&](StageStatus status, std::string failed_stage, std::string message) {
    result.status = status;
    result.failed_stage = std::move(failed_stage);
    result.message = std::move(message);
    result.seconds = total_timer.ElapsedSeconds();
    return result;
  };

  // A stage resumes only if every stage before it did, since it consumed their outputs.
  std::vector<StageRecord> finished = ReadFinishedStages(workspace, stages, options);
  const std::vector<StagePlan> plan = MakePlan(stages, finished.size());
  const std::vector<double> boundaries = StageBoundaries(plan);
  if (callbacks.on_plan) callbacks.on_plan(plan);

  for (std::size_t i = 0; i < stages.size(); ++i) {
    const Stage& stage = *stages[i];
    const std::string& name = plan[i].name;
    const fs::path stage_dir = workspace.StageDir(name);
    if (callbacks.on_stage_start) callbacks.on_stage_start(stage, boundaries[i]);

    if (i < finished.size()) {
      StageRecord& record = finished[i];
      record.resumed = true;
      record.resumable = stage.Resumable();
      LOG_INFO << "stage " << name << ": finished in an earlier run, resuming after it";
      if (callbacks.on_stage_end) callbacks.on_stage_end(stage, record, boundaries[i + 1]);
      result.stages.push_back(std::move(record));
      continue;
    }
    if (cancel.IsCanceled()) {
      return finish(StageStatus::kCanceled, name, "canceled before stage " + name);
    }
    const Status prepared = PrepareStageDir(stage, stage_dir, options, i == finished.size());
    if (!prepared.ok()) return finish(StageStatus::kFailed, name, prepared.message());

    const double start = boundaries[i];
    const double end = boundaries[i + 1];
    Progress progress([&](const ProgressUpdate& update) {
      if (callbacks.on_progress) {
        callbacks.on_progress(stage, update, start + (end - start) * update.fraction);
      }
    });
    StageContext context{workspace, options, progress, cancel, result.stages, stage_dir};
    StageRecord record = RunStage(stage, context, options);
    const bool succeeded = record.status == StageStatus::kSuccess;
    if (callbacks.on_stage_end) callbacks.on_stage_end(stage, record, succeeded ? end : start);
    const StageStatus status = record.status;
    std::string message = record.message;
    result.stages.push_back(std::move(record));
    if (!succeeded) return finish(status, name, std::move(message));
  }
  return finish(StageStatus::kSuccess, "", "");
}

}  // namespace reconduit
