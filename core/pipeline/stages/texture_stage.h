// Stage 8: the texture, and model.glb. From the mesh stage's surface and the original photos
// (with their distortion), one photo per face, charts packed into atlas pages, seams levelled
// (core/texture/texture_mesh.h); the textured mesh and the cameras are written at once as
// work/texture/model.glb (core/io/gltf.h), which the export stage delivers.
//
// Skipped, not failed, when there is nothing to texture: turned off (option texture), the mesh
// stage skipped or did not run. The export then writes an untextured model.glb with the mesh's
// vertex colours when there is a mesh (ExportUntexturedModel).
#ifndef RECONDUIT_CORE_PIPELINE_STAGES_TEXTURE_STAGE_H_
#define RECONDUIT_CORE_PIPELINE_STAGES_TEXTURE_STAGE_H_

#include "core/pipeline/stage.h"

#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

class TextureStage : public Stage {
 public:
  std::string_view Name() const override { return "texture"; }
  std::string_view Title() const override { return "Texturing the surface"; }
  double Weight() const override { return 1.0; }
  std::vector<std::string> OptionsUsed() const override {
    return {"texture", "texture_page_size", "held_out_photos"};
  }
  StageResult Run(StageContext& context) const override;
};

// The export stage's entries: model.glb from work/texture/ (textured), or from work/mesh/'s
// mesh.ply with vertex colours when the texture stage did not run or skipped. Each returns the
// files written, relative to `out` (nothing when its input is missing).
Result<std::vector<std::string>> ExportTexturedModel(const Workspace& workspace,
                                                     const std::filesystem::path& out);
Result<std::vector<std::string>> ExportUntexturedModel(const Workspace& workspace,
                                                       const std::filesystem::path& out);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_STAGES_TEXTURE_STAGE_H_
