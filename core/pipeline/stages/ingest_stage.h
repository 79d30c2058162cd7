// Stage 1: inspect every photo (format, size, EXIF focal) and decide which ones are usable.
//
// Writes work/ingest/images.json: one record per input photo, in input order, with the reason
// for each refusal. Later stages read it with ReadIngestedImages. At least two usable photos
// are needed; otherwise the stage fails with every refusal reason in its message.
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_INGEST_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_INGEST_STAGE_H_

#include "core/image/photo_metadata.h"
#include "core/pipeline/stage.h"

#include <optional>
#include <string>
#include <vector>

namespace reconduit {

// One photo as ingest saw it: its place in the workspace and its facts (photo_metadata.h).
struct IngestedImage {
  int index = -1;              // Position in the workspace's image list.
  std::string name;            // Display name.
  std::filesystem::path path;  // Where the bytes are.
  // Size, EXIF and acceptance; photo.reason does not repeat the name. photo.bytes is not
  // written to images.json (0 when read back).
  PhotoMetadata photo;
  // Photos with equal keys share intrinsics: EXIF make, model and size, or the size alone
  // for photos without EXIF.
  std::string camera_key;

  nlohmann::json ToJson() const;
  static IngestedImage FromJson(const nlohmann::json& json);
};

class IngestStage : public Stage {
 public:
  std::string_view Name() const override { return "ingest"; }
  std::string_view Title() const override { return "Reading photos"; }
  double Weight() const override { return 0.5; }
  std::vector<std::string> OptionsUsed() const override {
    return {"min_image_side", "max_image_pixels"};
  }
  StageResult Run(StageContext& context) const override;
};

// The ingest stage's records (all photos, accepted or not), from work/ingest/images.json.
Result<std::vector<IngestedImage>> ReadIngestedImages(const Workspace& workspace);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_INGEST_STAGE_H_
