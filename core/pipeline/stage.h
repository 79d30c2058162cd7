// The stage interface the worker and the command line drive.
//
// A stage is a step of the pipeline (ingest, features, matching, ...) that reads its inputs
// from the workspace (the photos, earlier stages' folders), writes its outputs into its own
// folder work/<name>/ (and final deliverables into output/), reports progress in natural
// units and honours the cancel token. Stages share nothing else, so each can be tested alone
// and a job can restart from the first unfinished stage.
#ifndef RECONDUIT_CORE_PIPELINE_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGE_H_

#include "core/io/result_archive.h"
#include "core/options/pipeline_options.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

// A photo given to the pipeline.
struct InputImage {
  std::filesystem::path path;  // Where the bytes are (a generated name for uploads).
  std::string name;            // The name to show and to export (as uploaded).
};

// Where a run reads and writes.
struct Workspace {
  std::vector<InputImage> images;
  // Per-stage folders work_dir/<stage>/ with the stage's outputs and its stage.json marker.
  std::filesystem::path work_dir;
  // Deliverables, laid out exactly as inside result.zip; the zip may leave some out
  // (package_dense_files), its manifest.json lists what it holds.
  std::filesystem::path output_dir;
  // Where the packaging stage writes the zip; empty for no zip (the command line).
  std::filesystem::path archive_path;

  std::filesystem::path StageDir(std::string_view stage) const { return work_dir / stage; }
};

enum class StageStatus { kSuccess, kCanceled, kFailed, kDegenerate };
std::string_view StageStatusName(StageStatus status);

// What the packaging stage delivered: the archive it wrote at Workspace::archive_path.
//
// A typed field of the stage's result (and record) rather than keys of its JSON summary, so the
// worker stores the archive's size and SHA-256 without looking figures up by name, and a
// rename in the stage cannot silently break the job's result. It wraps core/io's own summary
// of the archive (file list, bytes, SHA-256) instead of copying its fields. A later stage that
// hands something to the caller gets its own typed field the same way.
struct PackageResult {
  std::filesystem::path archive_path;
  ResultArchiveSummary archive;
};

// What a stage returns. Defaults read as "did not run" (a failure), never as a success.
struct StageResult {
  StageStatus status = StageStatus::kFailed;
  std::string message = "stage did not run";
  // Counts and figures for the report and the job status (e.g. {"accepted": 11}).
  nlohmann::json summary = nlohmann::json::object();
  // Set by the packaging stage when it wrote an archive.
  std::optional<PackageResult> package;

  static StageResult Success(nlohmann::json summary = nlohmann::json::object()) {
    return {StageStatus::kSuccess, "", std::move(summary), std::nullopt};
  }
  static StageResult Failed(std::string message) {
    return {StageStatus::kFailed, std::move(message), nlohmann::json::object(), std::nullopt};
  }
  static StageResult Degenerate(std::string message) {
    return {StageStatus::kDegenerate, std::move(message), nlohmann::json::object(), std::nullopt};
  }
  // A stage that could not do its work on these photos (dense matching with one camera, a mesh
  // without dense points): a success whose summary's "skipped_reason" says why, which the
  // report, the job status and the page show; the job goes on. Logs a warning naming `stage`.
  static StageResult Skipped(std::string_view stage,
                             const std::string& reason,
                             nlohmann::json summary = nlohmann::json::object());
};

// A finished (or resumed) stage, as the runner records it in work/<stage>/stage.json.
struct StageRecord {
  std::string name;
  StageStatus status = StageStatus::kFailed;
  std::string message;
  double seconds = 0.0;
  std::int64_t peak_memory_bytes = 0;  // Process peak RSS when the stage ended.
  // The stage's own peak RSS: the high-water mark since it began (StagePeakMemory), which
  // includes what the process held then. 0 when unknown (markers written before it was kept).
  std::int64_t stage_peak_memory_bytes = 0;
  // False when the kernel's mark could not be reset: stage_peak_memory_bytes is then the
  // process's peak, not the stage's own.
  bool stage_peak_memory_own = false;
  nlohmann::json summary = nlohmann::json::object();
  // The values of the stage's OptionsUsed() it ran with, {name: value}.
  nlohmann::json options = nlohmann::json::object();
  bool resumed = false;  // Taken from an earlier run instead of run again.
  // The stage's Resumable(): a later run may take its output over. Not written to stage.json
  // (the runner sets it from the stage).
  bool resumable = true;
  // The packaging stage's archive (StageResult::package); not written to stage.json either:
  // packaging is not resumable.
  std::optional<PackageResult> package;

  nlohmann::json ToJson() const;
  static StageRecord FromJson(const nlohmann::json& json);
};

struct StageContext {
  const Workspace& workspace;
  const PipelineOptions& options;
  Progress& progress;
  const CancelToken& cancel;
  // Records of the stages before this one, in order.
  const std::vector<StageRecord>& previous;
  // This stage's folder, empty and created by the runner.
  std::filesystem::path stage_dir;
};

class Stage {
 public:
  virtual ~Stage() = default;
  // Short machine name, also the folder name: "ingest", "features", ...
  virtual std::string_view Name() const = 0;
  // What a person reads in the status: "Reading photos".
  virtual std::string_view Title() const = 0;
  // Expected share of the whole run's time, for the overall progress figure (any scale).
  virtual double Weight() const { return 1.0; }
  // False for a stage that must run every time (packaging: its output depends on which
  // stages ran). A non-resumable stage also ends resuming for the stages after it.
  virtual bool Resumable() const { return true; }
  // True for a stage that keeps the parts it finished when a run is interrupted inside it (the
  // dense stage's depth maps, one per photo), so that the next run redoes only the rest. The
  // runner then leaves the stage's folder as the interrupted attempt left it, provided every
  // stage before it resumed and the options the stage uses are unchanged (recorded in
  // attempt.json when an attempt starts); otherwise it empties the folder as for any stage.
  // The stage must treat what it finds as unverified: parts are written atomically, and it
  // checks each one before using it.
  virtual bool KeepsFinishedParts() const { return false; }
  // The pipeline options this stage's outputs depend on (names from PipelineOptionSpecs). The
  // runner records their values in stage.json and resumes the stage only while they are
  // unchanged, so a rerun with other options never reuses outputs made with the old ones.
  // The default, every option that affects results, is always safe; a stage narrows it so
  // that changing an option reruns only the stages it concerns (and those after them).
  virtual std::vector<std::string> OptionsUsed() const;
  // Does the work. May throw CanceledError (canceled) or any exception (failed).
  virtual StageResult Run(StageContext& context) const = 0;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGE_H_
