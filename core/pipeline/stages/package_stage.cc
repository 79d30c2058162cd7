#include "core/pipeline/stages/package_stage.h"

#include "core/io/file_util.h"
#include "core/io/reconstruction_json.h"
#include "core/io/result_archive.h"
#include "core/pipeline/held_out.h"
#include "core/pipeline/report_html.h"
#include "core/pipeline/stages/dense_stage.h"
#include "core/pipeline/stages/export_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/util/timer.h"

#include <filesystem>
#include <optional>
#include <set>
#include <utility>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// What package_dense_files = false leaves out of result.zip: the dense cloud and the full-size
// maps, most of a dense job's bytes. The previews in report/dense/ stay.
const ArchiveExclusions& DenseFiles() {
  static const ArchiveExclusions files = {"dense.ply", "depth/", "quality/"};
  return files;
}

nlohmann::json ReportJson(const StageContext& context) {
  nlohmann::json stages = nlohmann::json::array();
  double seconds = 0.0;
  for (const StageRecord& record : context.previous) {
    stages.push_back(record.ToJson());
    seconds += record.seconds;
  }
  return {
      {"reconduit_report_version", 1},
      {"image_count", context.workspace.images.size()},
      {"options", PipelineOptionsToJson(context.options)},
      {"stages", stages},
      {"total_seconds", seconds},
      {"peak_memory_bytes", PeakMemoryBytes()},
  };
}

// Every photo with what report.html shows of it. Without ingest records (a pipeline without
// the ingest stage, in tests) the photos are listed by name only.
std::vector<ReportPhoto> ReportPhotos(const Workspace& workspace,
                                      const std::vector<std::string>& held_out) {
  std::vector<ReportPhoto> photos;
  auto images = ReadIngestedImages(workspace);
  if (!images.ok()) {
    for (std::size_t i = 0; i < workspace.images.size(); ++i)
      photos.push_back({.index = static_cast<int>(i), .name = workspace.images[i].name});
    return photos;
  }
  const std::map<int, std::string> thumbnails = ThumbnailPaths(*images);
  std::set<int> registered;
  std::map<int, std::string> stems;  // The dense stage's names for the photos it matched.
  if (auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
      model.ok()) {
    for (const auto& [id, image] : model->images) registered.insert(id);
    stems = PerPhotoFileNames(WithoutHeldOutPhotos(*model, held_out));
  }
  for (const IngestedImage& image : *images) {
    ReportPhoto photo{.index = image.index,
                      .name = image.name,
                      .accepted = image.photo.accepted,
                      .refusal = image.photo.reason};
    if (const auto it = thumbnails.find(image.index); it != thumbnails.end())
      photo.thumbnail = it->second;
    photo.registered = registered.count(image.index) > 0;
    if (const auto it = stems.find(image.index); it != stems.end()) {
      photo.depth_preview = "report/dense/" + it->second + "_depth.jpg";
      photo.quality_preview = "report/dense/" + it->second + "_quality.png";
      photo.depth_map = "depth/" + it->second + ".png";
      photo.quality_map = "quality/" + it->second + ".png";
    }
    photos.push_back(std::move(photo));
  }
  return photos;
}

// Writes output/report.html for an archive that will hold `files` (plus the page and the
// manifest when there is an archive); `excluded` is what the options leave out of it.
Status WriteReportHtml(const Workspace& workspace,
                       const PipelineOptions& options,
                       const nlohmann::json& report,
                       const std::vector<std::string>& files,
                       const ArchiveExclusions& excluded) {
  ReportHtmlInput input;
  input.report = report;
  input.photos = ReportPhotos(workspace, options.held_out_photos);
  input.files = std::set<std::string>(files.begin(), files.end());
  input.files.insert("report.html");
  if (!workspace.archive_path.empty()) input.files.insert("manifest.json");
  for (const std::string& entry : excluded) {
    // Only what this job has is worth a note (no dense.ply when the dense stage skipped).
    std::error_code ec;
    if (fs::exists(workspace.output_dir / entry, ec)) input.left_out.push_back(entry);
  }
  input.left_out_option = "package_dense_files";
  return WriteFileAtomically(workspace.output_dir / "report.html", RenderReportHtml(input));
}

}  // namespace

StageResult PackageStage::Run(StageContext& context) const {
  const Workspace& workspace = context.workspace;
  context.progress.Restart(3, "writing report.json");
  std::error_code ec;
  fs::create_directories(workspace.output_dir, ec);
  if (ec) return StageResult::Failed("cannot create " + workspace.output_dir.string());
  const nlohmann::json report = ReportJson(context);
  if (Status s = WriteFileAtomically(workspace.output_dir / "report.json", report.dump(2) + "\n");
      !s.ok()) {
    return StageResult::Failed(s.message());
  }
  context.progress.Advance();

  // The lean archive applies to result.zip only: the command line's folder keeps everything.
  const bool lean = !workspace.archive_path.empty() && !context.options.package_dense_files;
  const ArchiveExclusions excluded = lean ? DenseFiles() : ArchiveExclusions();
  context.progress.SetMessage("writing report.html");
  auto files = ListResultFiles(workspace.output_dir, excluded);
  if (!files.ok()) return StageResult::Failed(files.status().message());
  if (Status s = WriteReportHtml(workspace, context.options, report, *files, excluded); !s.ok())
    return StageResult::Failed(s.message());
  context.progress.Advance();

  nlohmann::json summary = nlohmann::json::object();
  std::optional<PackageResult> package;
  if (!workspace.archive_path.empty()) {
    context.progress.SetMessage("writing result.zip");
    auto archive =
        WriteResultArchive(workspace.output_dir, workspace.archive_path, context.cancel, excluded);
    if (!archive.ok()) return StageResult::Failed(archive.status().message());
    summary["files"] = archive->files.size();
    summary["archive_bytes"] = archive->archive_bytes;
    summary["archive_sha256"] = archive->archive_sha256;
    if (lean) summary["left_out"] = excluded;
    package = PackageResult{workspace.archive_path, std::move(archive).value()};
  }
  context.progress.Finish();
  StageResult result = StageResult::Success(std::move(summary));
  result.package = std::move(package);
  return result;
}

}  // namespace reconduit
