// The pipeline's stages in order, as the worker and the command line run them.
#ifndef RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_
#define RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_

#include "core/pipeline/stage.h"
#include "core/util/status.h"

#include <memory>
#include <string>
#include <vector>

namespace reconduit {

// Names of the stages that can end a run (`--until`), in pipeline order. Export and packaging
// are not among them: they always run, last.
std::vector<std::string> PipelineStageNames();

// Every stage up to and including `until` (empty: all), then export (the deliverables of the
// stages that ran into output/, stages/export_stage.h) and packaging, always last, so that a
// partial run still delivers its results, a report and an archive. InvalidArgument for an
// unknown name.
Result<std::vector<std::unique_ptr<Stage>>> CreatePipelineStages(const std::string& until = "");

}  // namespace reconduit

#endif  // RECONDUIT_CORE_PIPELINE_DEFAULT_STAGES_H_
