#include "core/pipeline/default_stages.h"

#include "core/pipeline/stages/dense_stage.h"
#include "core/pipeline/stages/export_stage.h"
#include "core/pipeline/stages/features_stage.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/pipeline/stages/matching_stage.h"
#include "core/pipeline/stages/mesh_stage.h"
#include "core/pipeline/stages/package_stage.h"
#include "core/pipeline/stages/pairs_stage.h"
#include "core/pipeline/stages/sparse_stage.h"
#include "core/pipeline/stages/texture_stage.h"

#include <functional>
#include <utility>

namespace reconduit {
namespace {

using StageFactory = std::function<std::unique_ptr<Stage>()>;

// The stages that can end a run (`--until`), in order. A stage is listed here when it exists.
std::vector<std::pair<std::string, StageFactory>> WorkStages() {
  return {
      {"ingest", [] { return std::make_unique<IngestStage>(); }},
      {"features", [] { return std::make_unique<FeaturesStage>(); }},
      {"pairs", [] { return std::make_unique<PairsStage>(); }},
      {"matching", [] { return std::make_unique<MatchingStage>(); }},
      {"sparse", [] { return std::make_unique<SparseStage>(); }},
      {"dense", [] { return std::make_unique<DenseStage>(); }},
      {"mesh", [] { return std::make_unique<MeshStage>(); }},
      {"texture", [] { return std::make_unique<TextureStage>(); }},
  };
}

}  // namespace

std::vector<std::string> PipelineStageNames() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : WorkStages()) names.push_back(name);
  return names;
}

Result<std::vector<std::unique_ptr<Stage>>> CreatePipelineStages(const std::string& until) {
  std::vector<std::unique_ptr<Stage>> stages;
  bool found = until.empty();
  for (const auto& [name, factory] : WorkStages()) {
    stages.push_back(factory());
    if (name == until) {
      found = true;
      break;
    }
  }
  if (!found) {
    std::string known;
    for (const std::string& name : PipelineStageNames())
      known += (known.empty() ? "" : ", ") + name;
    return Status::InvalidArgument("unknown stage '" + until + "'; stages: " + known);
  }
  // Export and packaging run every time, whatever `until` is: a partial run still delivers
  // what its stages produced, a report and an archive.
  stages.push_back(std::make_unique<ExportStage>());
  stages.push_back(std::make_unique<PackageStage>());
  return stages;
}

}  // namespace reconduit
