// Stage 4: match the chosen pairs and verify them geometrically.
//
// For each pair from the pairs stage: exhaustive RootSIFT matching (ratio test, mutual check),
// then robust F and H with GRIC model selection (core/estimators/two_view_geometry.h). Pairs
// with a usable model keep the inliers of that model; pairs with epipolar geometry also get
// guided matches along F's epipolar lines (more and longer tracks). Writes work/matching/pairs.bin
// (binary, see matching_stage.cc) and work/matching/summary.json (per pair counts, model and GRIC,
// for people), and the match graph as a picture, output/report/match_graph.png.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_MATCHING_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_MATCHING_STAGE_H_

#include "core/estimators/two_view_geometry.h"
#include "core/feature/features.h"
#include "core/pipeline/stage.h"
#include "core/sfm/tracks.h"

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// One verified pair, as later stages read it.
struct VerifiedPair {
  PairMatches matches;  // Inliers of the chosen model.
  TwoViewModelType type = TwoViewModelType::kUndefined;
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  int num_putative = 0;  // Descriptor matches before geometric verification.
  int num_inliers_F = 0;
  int num_inliers_H = 0;
  double gric_F = 0.0;
  double gric_H = 0.0;
  // Matches added by guided matching along F's epipolar lines (included in `matches`; not
  // stored in pairs.bin).
  int num_guided = 0;
  // Verified again at a looser ratio test (few inliers at the default; not stored either).
  bool retried = false;
  // Matched again with affine-adapted features (not stored either): some of its matches may
  // refer to keypoints the matching stage added to the photo (ReadMatchedKeypoints).
  bool affine = false;
};

class MatchingStage : public Stage {
 public:
  std::string_view Name() const override { return "matching"; }
  std::string_view Title() const override { return "Matching photos"; }
  double Weight() const override { return 2.0; }
  std::vector<std::string> OptionsUsed() const override { return {}; }
  StageResult Run(StageContext& context) const override;
};

Result<std::vector<VerifiedPair>> ReadVerifiedPairs(const Workspace& workspace);

// Photo `index`'s keypoints as the matches in pairs.bin number them: its SIFT keypoints (the
// features stage), then those the matching stage added from affine-adapted features
// (work/matching/NNNNN.added.feat), if any.
Result<std::vector<Keypoint>> ReadMatchedKeypoints(const Workspace& workspace, int index);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_MATCHING_STAGE_H_
