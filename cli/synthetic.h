// `reconduit synthetic`: renders a synthetic aerial survey (core/scene/survey.h) as a photo
// folder with its exact cameras, for benchmarks at any size (issue 13's scaling figures,
// scripts/scaling_benchmark.sh).
//
//   reconduit synthetic <out_dir> [--rows R] [--cols C] [--seed S]
//                       [--width W] [--height H] [--focal F]
//
// Writes <out_dir>/images/NNNN.jpg (row by row, JPEG quality 95, no EXIF: the pipeline
// self-calibrates) and <out_dir>/cameras_par.txt (Middlebury format, what `reconduit benchmark
// --gt` reads). Refuses an <out_dir> that exists and is not empty.
#ifndef RECONDUIT_CLI_SYNTHETIC_H_
#define RECONDUIT_CLI_SYNTHETIC_H_

#include <string>
#include <vector>

namespace reconduit {

// Returns the process exit status (0 success, 1 failure, 2 usage).
int RunSynthetic(const std::vector<std::string>& args);

}  // namespace reconduit

#endif  // RECONDUIT_CLI_SYNTHETIC_H_
