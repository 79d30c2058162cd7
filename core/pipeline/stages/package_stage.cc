#include "core/pipeline/stages/package_stage.h"

#include "core/io/file_util.h"
#include "core/io/result_archive.h"
#include "core/util/timer.h"

#include <filesystem>
#include <optional>
#include <utility>

namespace reconduit {

StageResult PackageStage::Run(StageContext& context) const {
  namespace fs = std::filesystem;
  const Workspace& workspace = context.workspace;
  context.progress.Restart(2, "writing report.json");
  std::error_code ec;
  fs::create_directories(workspace.output_dir, ec);
  if (ec) return StageResult::Failed("cannot create " + workspace.output_dir.string());

  nlohmann::json stages = nlohmann::json::array();
  double seconds = 0.0;
  for (const StageRecord& record : context.previous) {
    stages.push_back(record.ToJson());
    seconds += record.seconds;
  }
  const nlohmann::json report = {
      {"reconduit_report_version", 1},
      {"image_count", workspace.images.size()},
      {"options", PipelineOptionsToJson(context.options)},
      {"stages", stages},
      {"total_seconds", seconds},
      {"peak_memory_bytes", PeakMemoryBytes()},
  };
  if (Status s = WriteFileAtomically(workspace.output_dir / "report.json", report.dump(2) + "\n");
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  context.progress.Advance();

  nlohmann::json summary = nlohmann::json::object();
  std::optional<PackageResult> package;
  if (!workspace.archive_path.empty()) {
    context.progress.SetMessage("writing result.zip");
    auto archive = WriteResultArchive(workspace.output_dir, workspace.archive_path, context.cancel);
    if (!archive.ok()) return StageResult::Failed(archive.status().message());
    summary["files"] = archive->files.size();
    summary["archive_bytes"] = archive->archive_bytes;
    summary["archive_sha256"] = archive->archive_sha256;
    package = PackageResult{workspace.archive_path, std::move(archive).value()};
  }
  context.progress.Finish();
  StageResult result = StageResult::Success(std::move(summary));
  result.package = std::move(package);
  return result;
}

}  // namespace reconduit
