// The stage before packaging: writes the deliverables into output/, laid out exactly as in
// result.zip, from what the earlier stages saved in work/.
//
// Each reconstruction stage saves its results in its own work folder only; this stage turns
// them into the formats people open. Today, from the sparse stage's largest model
// (work/sparse/model_0.json) and the ingest records:
//   cameras.json            every accepted photo's camera (core/io/cameras_json.h)
//   sparse/                 COLMAP text model (cameras.txt, images.txt, points3D.txt)
//   bundle/                 Bundler v0.3 (bundle.out, list.txt)
//   sparse.ply              the coloured sparse points
// and from the dense stage (dense_stage.h, unless it skipped):
//   dense.ply               the fused cloud with normals and visibility
//   depth/<name>.png, .json every photo's depth map (16-bit) with its range, camera and pose
//   quality/<name>.png      every photo's quality map (how many photos agree, 8-bit)
//   report/dense/           previews of both
// and from the ingest records:
//   report/photos/<name>.jpg  every accepted photo, at most 256 px (ThumbnailPaths)
// and from the mesh and texture stages (mesh_stage.h, texture_stage.h):
//   model.glb               the textured mesh with the cameras (untextured, with the mesh's
//                           vertex colours, when the texture stage did not run or skipped)
//   report/texture/         a few renders of the model beside their photos
// A stage that did not run (a run stopped early with --until) exports nothing. A later stage
// (dense points, mesh, texture) adds its deliverables with one entry in the exporter table of
// export_stage.cc.
//
// Not resumable, like packaging, and always run just before it (CreatePipelineStages), so
// that `--until <stage>` still delivers what the stages that ran produced. Why not resumable:
// output/ is not this stage's own folder. A run may resume with a fresh output/ (the command
// line's `--work` kept while the output folder changes, or an output folder deleted by hand),
// and a resumed export would then deliver nothing; writing the files again costs little next
// to the stages before it (well under a second for a sparse model). Being last before
// packaging, it never stops a resumable stage from resuming.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_EXPORT_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_EXPORT_STAGE_H_

#include "core/pipeline/stage.h"
#include "core/pipeline/stages/ingest_stage.h"

#include <map>
#include <string>
#include <vector>

namespace reconduit {

// Where the export puts each accepted photo's thumbnail, by ingest index: report/photos/
// <name>.jpg, <name> by the rule of the dense stage's per-photo files (PerPhotoFileNames)
// applied to every ingested photo. report.html finds the thumbnails with it.
std::map<int, std::string> ThumbnailPaths(const std::vector<IngestedImage>& images);

class ExportStage : public Stage {
 public:
  std::string_view Name() const override { return "export"; }
  std::string_view Title() const override { return "Writing the results"; }
  double Weight() const override { return 0.1; }
  bool Resumable() const override { return false; }
  // The exports depend on the earlier stages' outputs only.
  std::vector<std::string> OptionsUsed() const override { return {}; }
  StageResult Run(StageContext& context) const override;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_EXPORT_STAGE_H_
