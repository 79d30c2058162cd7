#include "core/pipeline/stages/mesh_stage.h"

#include "core/io/file_util.h"
#include "core/io/mesh_ply.h"
#include "core/io/reconstruction_json.h"
#include "core/mesh/mesh_cleaning.h"
#include "core/mesh/surface_reconstruction.h"
#include "core/mvs/dense_cloud_io.h"
#include "core/util/logging.h"
#include "core/util/timer.h"

#include <filesystem>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// The photos of the cloud's visibility ids: views.json lists the registered photos in
// increasing image id, the order the visibility refers to.
Result<std::vector<SurfaceView>> SurfaceViews(const Workspace& workspace) {
  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  if (!model.ok()) return model.status();
  auto text = ReadFile(workspace.StageDir("dense") / "views.json");
  if (!text.ok()) return text.status();
  const nlohmann::json views = nlohmann::json::parse(*text, nullptr, false);
  if (!views.is_array()) return Status::Internal("work/dense/views.json is not a list");
  std::vector<SurfaceView> result;
  int previous_id = -1;
  for (const nlohmann::json& view : views) {
    const int id = view.at("image_id").get<int>();
    if (id <= previous_id || !model->images.count(id))
      return Status::Internal("work/dense/views.json does not match the sparse model");
    previous_id = id;
    result.push_back({model->images.at(id).cam_from_world.CenterInWorld(),
                      view.at("camera").at("focal").get<double>()});
  }
  return result;
}

nlohmann::json SurfaceJson(const SurfaceSummary& s) {
  return {{"input_points", s.input_points},
          {"kept_points", s.kept_points},
          {"tetrahedra", s.cells},
          {"lines_of_sight", s.rays},
          {"facets_crossed", s.facets_crossed},
          {"inside_tetrahedra", s.inside_cells},
          {"relabelled_tetrahedra", s.relabelled_cells},
          {"cut_faces", s.cut_faces},
          {"trimmed_faces", s.trimmed_faces},
          {"unseen_faces", s.unseen_faces},
          {"seconds",
           {{"decimation", s.seconds_decimation},
            {"delaunay", s.seconds_delaunay},
            {"visibility", s.seconds_visibility},
            {"cut", s.seconds_cut},
            {"extraction", s.seconds_extraction}}}};
}

nlohmann::json CleaningJson(const CleaningSummary& s) {
  return {{"degenerate_faces", s.degenerate_faces},
          {"duplicate_faces", s.duplicate_faces},
          {"non_manifold_faces", s.non_manifold_faces},
          {"small_component_faces", s.small_component_faces},
          {"components", s.components},
          {"removed_components", s.removed_components}};
}

}  // namespace

StageResult MeshStage::Run(StageContext& context) const {
  if (!context.options.mesh) return StageResult::Skipped("mesh", "turned off (option mesh)");
  const fs::path dense = context.workspace.StageDir("dense") / "dense.ply";
  if (!fs::exists(dense))
    return StageResult::Skipped("mesh", "no dense point cloud (the dense stage skipped)");
  Result<DenseCloud> read = ReadDenseCloudPly(dense);
  if (!read.ok()) return StageResult::Failed(read.status().message());
  DenseCloud cloud = std::move(read).value();
  auto views = SurfaceViews(context.workspace);
  if (!views.ok()) return StageResult::Failed(views.status().message());

  SurfaceOptions options;
  options.num_threads = context.options.num_threads;
  SurfaceResult surface =
      ReconstructSurface(cloud, *views, options, &context.progress, context.cancel);
  cloud = DenseCloud();  // Free it before cleaning.
  nlohmann::json summary = {{"surface", SurfaceJson(surface.summary)}};
  TriangleMesh& mesh = surface.mesh;
  Timer timer;
  context.progress.SetMessage("cleaning and simplifying the surface");
  summary["cleaning"] = CleaningJson(CleanMesh(&mesh));
  context.cancel.ThrowIfCanceled();
  const SimplificationSummary simplified =
      SimplifyMesh(&mesh, static_cast<std::size_t>(context.options.mesh_max_faces));
  ComputeVertexNormals(&mesh);
  summary["simplification"] = {{"faces_before", simplified.faces_before},
                               {"faces_after", simplified.faces_after},
                               {"relative_error", simplified.relative_error},
                               {"seconds", timer.ElapsedSeconds()}};
  summary["faces"] = mesh.NumFaces();
  summary["vertices"] = mesh.NumVertices();
  if (mesh.NumFaces() == 0)
    return StageResult::Skipped("mesh", "no surface: too few dense points support one",
                                std::move(summary));
  const Status written = WriteMeshPly(context.stage_dir / "mesh.ply", mesh);
  if (!written.ok()) return StageResult::Failed(written.message());
  LOG_INFO << "mesh: " << mesh.NumFaces() << " faces, " << mesh.NumVertices() << " vertices ("
           << simplified.faces_before << " before simplification)";
  return StageResult::Success(std::move(summary));
}

}  // namespace reconduit
