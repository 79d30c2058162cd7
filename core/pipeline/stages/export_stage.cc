#include "core/pipeline/stages/export_stage.h"

#include "core/io/bundler.h"
#include "core/io/cameras_json.h"
#include "core/io/colmap_text.h"
#include "core/io/ply.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/stages/dense_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/texture_stage.h"

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
    {"sparse", ExportSparse},
    {"dense", ExportDenseResults},
    {"mesh", ExportUntexturedModel, "texture"},
    {"texture", ExportTexturedModel},
};

bool StageSucceeded(const std::vector<StageRecord>& previous, std::string_view stage) {
  return std::any_of(previous.begin(), previous.end(), [&](const StageRecord& record) {
    return record.name == stage && record.status == StageStatus::kSuccess;
  });
}

}  // namespace

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
