#include "core/pipeline/stages/export_stage.h"

#include "core/image/image_reader.h"
#include "core/io/bundler.h"
#include "core/io/cameras_json.h"
#include "core/io/colmap_text.h"
#include "core/io/ply.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/stages/dense_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/texture_stage.h"
#include "core/util/logging.h"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// The deliverables of the sparse stage's largest model: cameras.json, COLMAP text in sparse/,
// Bundler in bundle/, sparse.ply. Returns the files written, relative to `out`.
Result<std::vector<std::string>> ExportSparse(const Workspace& workspace, const fs::path& out) {
  auto best = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  if (!best.ok()) return best.status();
  auto images = ReadIngestedImages(workspace);
  if (!images.ok()) return images.status();
  std::vector<std::string> unregistered;
  for (const IngestedImage& image : *images) {
    if (image.photo.accepted && !best->images.count(image.index))
      unregistered.push_back(image.name);
  }
  std::error_code ec;
  fs::create_directories(out / "sparse", ec);
  if (!ec) fs::create_directories(out / "bundle", ec);
  if (ec) return Status::Internal("cannot create folders in " + out.string() + ": " + ec.message());
  for (const Status& s :
       {WriteCamerasJson(out / "cameras.json", *best, unregistered),
        WriteColmapText(out / "sparse", *best), WriteBundler(out / "bundle", *best),
        WritePointCloudPly(out / "sparse.ply", PointCloudFromReconstruction(*best))}) {
    if (!s.ok()) return s;
  }
  return std::vector<std::string>{"cameras.json",        "sparse/cameras.txt", "sparse/images.txt",
                                  "sparse/points3D.txt", "bundle/bundle.out",  "bundle/list.txt",
                                  "sparse.ply"};
}

// Longer side of the photo thumbnails in report/photos/, pixels: a table row of report.html.
constexpr int kThumbnailSide = 256;
constexpr int kThumbnailJpegQuality = 85;

// Every accepted photo as a small JPEG, upright (EXIF orientation applied, as every stage
// sees it), for report.html. Decoded again here because ingest keeps no pixels (a fraction of
// a second per 6 MP photo).
Result<std::vector<std::string>> ExportThumbnails(const Workspace& workspace, const fs::path& out) {
  auto images = ReadIngestedImages(workspace);
  if (!images.ok()) return images.status();
  ImageReaderOptions reader;
  // Ingest already applied the job's size limits; these only keep the reader's own checks
  // from refusing a photo it accepted.
  reader.min_side = 1;
  reader.max_pixels = std::int64_t{1} << 40;
  reader.max_side = kThumbnailSide;
  reader.read_exif = false;
  std::error_code ec;
  fs::create_directories(out / "report" / "photos", ec);
  if (ec) return Status::Internal("cannot create " + (out / "report" / "photos").string());
  std::vector<std::string> files;
  for (const auto& [index, path] : ThumbnailPaths(*images)) {
    auto pixels = ReadImage(images->at(index).path, reader);
    if (!pixels.ok()) {  // report.html says the picture is missing; the job goes on.
      LOG_WARNING << "export: no thumbnail of " << images->at(index).name << ": "
                  << pixels.status().message();
      continue;
    }
    if (!cv::imwrite((out / path).string(), *pixels,
                     {cv::IMWRITE_JPEG_QUALITY, kThumbnailJpegQuality}))
      return Status::Internal("cannot write " + (out / path).string());
    files.push_back(path);
  }
  return files;
}

// One entry per stage with deliverables, in pipeline order: the stage's name and the function
// that writes its deliverables into output/ from its work folder and returns the files it
// wrote (relative to output/). An entry runs when its stage ran (or resumed) successfully in
// this run, unless the stage named by `unless` did too (the untextured model.glb is written
// only where no textured one is).
struct Exporter {
  std::string_view stage;
  Result<std::vector<std::string>> (*write)(const Workspace& workspace, const fs::path& output_dir);
  std::string_view unless = "";
};
constexpr Exporter kExporters[] = {
    {"ingest", ExportThumbnails},     {"sparse", ExportSparse},
    {"dense", ExportDenseResults},    {"mesh", ExportUntexturedModel, "texture"},
    {"texture", ExportTexturedModel},
};

bool StageSucceeded(const std::vector<StageRecord>& previous, std::string_view stage) {
  return std::any_of(previous.begin(), previous.end(), [&](const StageRecord& record) {
    return record.name == stage && record.status == StageStatus::kSuccess;
  });
}

}  // namespace

std::map<int, std::string> ThumbnailPaths(const std::vector<IngestedImage>& images) {
  std::vector<std::string> names;
  std::vector<int> indices;
  for (const IngestedImage& image : images) {
    names.push_back(image.name);
    indices.push_back(image.index);
  }
  const std::vector<std::string> stems = PerPhotoFileNames(names, indices);
  std::map<int, std::string> paths;
  for (std::size_t k = 0; k < images.size(); ++k) {
    if (images[k].photo.accepted) paths[images[k].index] = "report/photos/" + stems[k] + ".jpg";
  }
  return paths;
}

StageResult ExportStage::Run(StageContext& context) const {
  const Workspace& workspace = context.workspace;
  std::vector<const Exporter*> due;
  for (const Exporter& exporter : kExporters) {
    if (StageSucceeded(context.previous, exporter.stage) &&
        (exporter.unless.empty() || !StageSucceeded(context.previous, exporter.unless)))
      due.push_back(&exporter);
  }
  context.progress.Restart(due.size(), "writing the deliverables");
  std::string exported;
  std::size_t files = 0;
  for (const Exporter* exporter : due) {
    context.cancel.ThrowIfCanceled();
    auto written = exporter->write(workspace, workspace.output_dir);
    if (!written.ok()) {
      return StageResult::Failed(std::string(exporter->stage) + ": " + written.status().message());
    }
    exported += (exported.empty() ? "" : ", ") + std::string(exporter->stage);
    files += written->size();
    context.progress.Advance();
  }
  context.progress.Finish();
  // "exported": the stages whose deliverables were written, e.g. "sparse"; "deliverables": how
  // many files.
  return StageResult::Success({{"exported", exported}, {"deliverables", files}});
}

}  // namespace reconduit
