// Stage 7: the surface. From the dense stage's cloud and the photos that see each point, a
// triangle mesh (core/mesh): Delaunay tetrahedra labelled by a visibility graph cut, trimmed
// where no data supports it, cleaned, simplified to mesh_max_faces, with vertex colours and
// normals.
//
// Reads work/dense/dense.ply (its visibility: positions in the registered photos, in
// increasing image id), work/dense/views.json (each photo's working camera: the focal length
// that gives the points' footprints) and the sparse model's poses. Writes work/mesh/mesh.ply
// (core/io/mesh_ply.h); the texture stage and the export take it from there.
//
// Skipped, not failed, when there is nothing to mesh: turned off (option mesh), the dense
// stage skipped or did not run, or no face survived (too few points). The summary's
// "skipped_reason" says why.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_MESH_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_MESH_STAGE_H_

#include "core/pipeline/stage.h"

namespace reconduit {

class MeshStage : public Stage {
 public:
  std::string_view Name() const override { return "mesh"; }
  std::string_view Title() const override { return "Building the surface"; }
  double Weight() const override { return 2.0; }
  std::vector<std::string> OptionsUsed() const override { return {"mesh", "mesh_max_faces"}; }
  StageResult Run(StageContext& context) const override;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_MESH_STAGE_H_
