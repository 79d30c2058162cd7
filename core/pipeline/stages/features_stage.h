// Stage 2: SIFT features of every usable photo.
//
// Writes work/features/<index>.feat (core/feature/features.h format) for each accepted photo,
// index being the photo's position in the input. Photos are processed in parallel.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_FEATURES_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_FEATURES_STAGE_H_

#include "core/feature/features.h"
#include "core/pipeline/stage.h"

namespace reconduit {

class FeaturesStage : public Stage {
 public:
  std::string_view Name() const override { return "features"; }
  std::string_view Title() const override { return "Finding features"; }
  double Weight() const override { return 3.0; }
  // The decoding limits (min_image_side, max_image_pixels) only guard what ingest accepted.
  std::vector<std::string> OptionsUsed() const override {
    return {"max_image_side", "max_features"};
  }
  StageResult Run(StageContext& context) const override;
};

// Where the features stage keeps the features of input photo `index`.
std::filesystem::path FeaturesPath(const Workspace& workspace, int index);

// Reads them back.
Result<FeatureSet> ReadImageFeatures(const Workspace& workspace, int index);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_FEATURES_STAGE_H_
