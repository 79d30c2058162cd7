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

nlohmann::json StageRecord::ToJson() const {
  return {{"name", name},       {"status", StageStatusName(status)},      {"message", message},
          {"seconds", seconds}, {"peak_memory_bytes", peak_memory_bytes}, {"summary", summary},
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

PipelineResult RunPipeline(const std::vector<std::unique_ptr<Stage>>& stages,
                           const Workspace& workspace,
                           const PipelineOptions& options,
                           const CancelToken& cancel,
                           const PipelineCallbacks& callbacks) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const Timer total_timer;
  PipelineResult result;

  double total_weight = 0.0;
  for (const auto& stage : stages) total_weight += stage->Weight();
  double weight_done = 0.0;

  auto finish = [&](StageStatus status, std::string failed_stage, std::string message) {
    result.status = status;
    result.failed_stage = std::move(failed_stage);
    result.message = std::move(message);
    result.seconds = total_timer.ElapsedSeconds();
    return result;
  };

  // A stage resumes only if every stage before it did, since it consumed their outputs.
  bool may_resume = true;
  for (const auto& stage_ptr : stages) {
    const Stage& stage = *stage_ptr;
    const std::string name(stage.Name());
    const fs::path stage_dir = workspace.StageDir(name);
    if (callbacks.on_stage_start) callbacks.on_stage_start(stage);

    if (!stage.Resumable()) may_resume = false;
    if (may_resume) {
      if (auto record = ReadMarker(stage, stage_dir, options)) {
        record->resumed = true;
        LOG_INFO << "stage " << name << ": finished in an earlier run, resuming after it";
        weight_done += stage.Weight();
        if (callbacks.on_stage_end) callbacks.on_stage_end(stage, *record);
        result.stages.push_back(std::move(*record));
        continue;
      }
      may_resume = false;
    }

    if (cancel.IsCanceled()) {
      return finish(StageStatus::kCanceled, name, "canceled before stage " + name);
    }

    std::error_code ec;
    fs::remove_all(stage_dir, ec);  // Outputs of an interrupted earlier attempt.
    fs::create_directories(stage_dir, ec);
    if (ec) {
      return finish(StageStatus::kFailed, name,
                    "cannot create " + stage_dir.string() + ": " + ec.message());
    }

    const double weight_before = weight_done;
    Progress progress([&](const ProgressUpdate& update) {
      if (!callbacks.on_progress) return;
      const double overall =
          total_weight > 0 ? (weight_before + stage.Weight() * update.fraction) / total_weight : 0;
      callbacks.on_progress(stage, update, overall);
    });

    LOG_INFO << "stage " << name << ": " << stage.Title();
    const Timer timer;
    StageRecord record;
    record.name = name;
    record.options = UsedOptionValues(stage, options);
    StageContext context{workspace, options, progress, cancel, result.stages, stage_dir};
    try {
      StageResult stage_result = stage.Run(context);
      record.status = stage_result.status;
      record.message = std::move(stage_result.message);
      record.summary = std::move(stage_result.summary);
    } catch (const CanceledError&) {
      record.status = StageStatus::kCanceled;
      record.message = "canceled during stage " + name;
    } catch (const std::exception& e) {
      record.status = StageStatus::kFailed;
      record.message = e.what();
    }
    record.seconds = timer.ElapsedSeconds();
    record.peak_memory_bytes = PeakMemoryBytes();

    if (record.status == StageStatus::kSuccess) {
      progress.Finish();  // The overall figure reaches this stage's end even if throttled.
      const Status written =
          WriteFileAtomically(stage_dir / kMarker, record.ToJson().dump(2) + "\n");
      if (!written.ok()) {
        record.status = StageStatus::kFailed;
        record.message = "cannot record the end of the stage: " + written.message();
      }
    }
    LOG_INFO << "stage " << name << ": " << StageStatusName(record.status) << " in "
             << record.seconds << " s" << (record.message.empty() ? "" : ": ") << record.message;
    if (callbacks.on_stage_end) callbacks.on_stage_end(stage, record);
    const StageStatus status = record.status;
    std::string message = record.message;
    result.stages.push_back(std::move(record));
    if (status != StageStatus::kSuccess) return finish(status, name, std::move(message));
    weight_done += stage.Weight();
  }
  return finish(StageStatus::kSuccess, "", "");
}

}  // namespace reconduit
