// Pieces shared by the `reconduit` commands (reconstruct, benchmark).
#ifndef RECONDUIT_CLI_CLI_COMMON_H_
#define RECONDUIT_CLI_CLI_COMMON_H_

#include "core/options/pipeline_options.h"
#include "core/pipeline/stage.h"

#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

// Pipeline options from a JSON file (empty: the defaults), then `threads` when >= 0.
// InvalidArgument naming the file or the field for bad input.
Result<PipelineOptions> LoadPipelineOptions(const std::string& options_file, int threads);

// Every regular, non-hidden file of `folder`, sorted by name, as pipeline inputs (the
// ingest stage tells photos from other files).
std::vector<InputImage> ListInputImages(const std::filesystem::path& folder);

}  // namespace reconduit

#endif  // RECONDUIT_CLI_CLI_COMMON_H_
