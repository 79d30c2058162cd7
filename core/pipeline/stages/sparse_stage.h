// Stage 5: structure and motion with self-calibration.
//
//  - Photos that share a camera (same EXIF make, model and size; or the same size in photos
//    without EXIF) share intrinsics.
//  - Each camera's initial focal length (core/sfm/initial_calibration.h): with use_exif, an
//    EXIF focal length, and a clear disagreement with self-calibration is reported; otherwise
//    self-calibrated from the fundamental matrices of its photo pairs
//    (core/sfm/self_calibration.h); with neither, 1.2 x the longer side is assumed (a common
//    phone/compact field of view) and a warning says so; bundle adjustment refines it either
//    way.
//  - Tracks from the verified matches; incremental reconstruction (core/sfm/incremental_mapper.h).
//  - Point colours are the mean colour of their observations.
// Writes work/sparse/model_<k>.json (largest first) and work/sparse/calibration.json; the
// export stage (export_stage.h) writes the largest model's deliverables into output/.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_SPARSE_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_SPARSE_STAGE_H_

#include "core/pipeline/stage.h"
#include "core/scene/reconstruction.h"

#include <vector>

namespace reconduit {

class SparseStage : public Stage {
 public:
  std::string_view Name() const override { return "sparse"; }
  std::string_view Title() const override { return "Recovering cameras and structure"; }
  double Weight() const override { return 3.0; }
  StageResult Run(StageContext& context) const override;
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_SPARSE_STAGE_H_
