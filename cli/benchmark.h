// `reconduit benchmark`: the pipeline on a photo folder, with figures.
//
//   reconduit benchmark <images_dir> [--gt PATH] [--colmap] [--until STAGE]
//                       [--options FILE] [--work DIR] [--threads N] [--resume]
//
// Runs the stages up to --until (default: sparse) from scratch in a work folder and prints
// per-stage wall time and peak memory, registered photos, points, mean reprojection error,
// and — with --gt (a Strecha folder of .camera files or a Middlebury *_par.txt) — camera
// accuracy after a 7-DoF alignment. With --colmap it also runs Debian's COLMAP (CPU:
// feature_extractor, exhaustive_matcher, mapper) on the same photos in the same run, prints
// its times, peak memory and accuracy, and the ratios ours / COLMAP. --resume keeps the
// work folder's finished stages (to tune a late stage, delete its folder and rerun).
#ifndef RECONDUIT_CLI_BENCHMARK_H_
#define RECONDUIT_CLI_BENCHMARK_H_

#include <string>
#include <vector>

namespace reconduit {

// Returns the process exit status (0 success, 1 failure, 2 usage).
int RunBenchmark(const std::vector<std::string>& args);

}  // namespace reconduit

#endif  // RECONDUIT_CLI_BENCHMARK_H_
