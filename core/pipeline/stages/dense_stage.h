// Stage 6: dense matching. A depth map and a quality map for every registered photo, fused
// into one coloured point cloud with normals and visibility (core/mvs).
//
// From the sparse stage's largest model (work/sparse/model_0.json):
//  1. View selection (core/mvs/view_selection.h): each photo's neighbours, scored from the
//     sparse points they share. The best kMaxSources are its PatchMatch sources.
//  2. For each photo, in turn: its working copy and its sources' (undistorted, longer side at
//     most dense_max_image_side; core/mvs/mvs_view.h; a small cache keeps the last few), its
//     depth range and seeds from the sparse points it sees, and PatchMatch
//     (core/mvs/patch_match.h). Each finished map is written at once to
//     work/dense/maps/<image id>.rcdm: a worker killed in the middle resumes at the first
//     unfinished map (Stage::KeepsFinishedParts). Memory holds one map and the cache, whatever
//     the number of photos.
//  3. Fusion (core/mvs/fusion.h) of the maps that agree across photos (at least
//     dense_min_views), with ARC3D's quality maps. Fusion holds every map at once (about 32 MB
//     a photo at 1600 px); streaming it is future work for sets of hundreds of photos.
// Writes work/dense/: views.json (per photo: its working camera, neighbours, depth range and
// seeds), maps/, quality/<image id>.png, dense.ply (core/mvs/dense_cloud_io.h). The export
// stage turns them into output/dense.ply, output/depth/<name>.png + .json,
// output/quality/<name>.png and previews in output/report/dense/ (ExportDenseResults).
//
// Skipped, not failed, when dense matching cannot work: turned off (dense_matching), fewer
// than two registered photos, no photo with a neighbour, or no point confirmed by enough
// photos (no texture anywhere). The job still succeeds with the cameras and sparse points;
// the summary's "skipped_reason" says why, and the report and the page show it.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_DENSE_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_DENSE_STAGE_H_

#include "core/pipeline/stage.h"
#include "core/scene/reconstruction.h"

#include <map>
#include <string>
#include <vector>

namespace reconduit {

class DenseStage : public Stage {
 public:
  std::string_view Name() const override { return "dense"; }
  std::string_view Title() const override { return "Computing depth maps"; }
  double Weight() const override { return 5.0; }
  bool KeepsFinishedParts() const override { return true; }
  std::vector<std::string> OptionsUsed() const override {
    return {"dense_matching", "dense_max_image_side", "dense_min_views", "held_out_photos"};
  }
  StageResult Run(StageContext& context) const override;
};

// The names of the per-photo files (depth/<name>.png, ...): each photo's name as uploaded
// without folders and extension; where several photos share that stem, each of them gets
// "_<k>" appended, k its 1-based position in the upload (`indices`). Characters other than
// letters, digits, '-', '_' and '.' become '_'.
std::vector<std::string> PerPhotoFileNames(const std::vector<std::string>& names,
                                           const std::vector<int>& indices);

// The same names for a model's photos, by image id: those ExportDenseResults gives the files
// of the model the dense stage matched (the sparse model without the held-out photos; its
// depth maps are that model's photos, in image id order).
std::map<int, std::string> PerPhotoFileNames(const Reconstruction& model);

// The dense stage's deliverables from work/dense/ into `out` (the export stage's table):
// dense.ply, depth/<name>.png and .json, quality/<name>.png, and report/dense/<name>_depth.jpg
// and <name>_quality.png previews. Nothing when the stage skipped. Returns the files written,
// relative to `out`.
Result<std::vector<std::string>> ExportDenseResults(const Workspace& workspace,
                                                    const std::filesystem::path& out);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_DENSE_STAGE_H_
