// The pipeline's stages in order, as the worker and the command line run them.
#ifndef RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_
#define RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_

#include "core/pipeline/stage.h"
#include "core/util/status.h"

#include <memory>
#include <string>
#include <vector>

namespace reconduit {

// Names of the stages that can end a run (`--until`), in pipeline order.
std::vector<std::string> PipelineStageNames();

// Every stage up to and including `until` (empty: all), then packaging (always last, so a
// partial run still delivers a report and an archive). InvalidArgument for an unknown name.
Result<std::vector<std::unique_ptr<Stage>>> CreatePipelineStages(const std::string& until = "");

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_
