// Stage 3: global image comparison — which pairs of photos to match.
//
// Writes work/pairs/pairs.json ({"method", "images": [input indices], "pairs": [{"image1",
// "image2", "score"}], "similarity": N x N rows}) with input indices, and the similarity
// matrix as a picture, output/report/similarity.png.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_PAIRS_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_PAIRS_STAGE_H_

#include "core/feature/global_comparison.h"
#include "core/pipeline/stage.h"

#include <vector>

namespace reconduit {

class PairsStage : public Stage {
 public:
  std::string_view Name() const override { return "pairs"; }
  std::string_view Title() const override { return "Comparing photos"; }
  double Weight() const override { return 0.5; }
  std::vector<std::string> OptionsUsed() const override { return {}; }
  StageResult Run(StageContext& context) const override;
};

// The chosen pairs, with input indices, best first.
Result<std::vector<ImagePair>> ReadImagePairs(const Workspace& workspace);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_PAIRS_STAGE_H_
