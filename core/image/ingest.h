// Ingest (DESIGN.md §4, step 1): inspect a set of uploaded photos and report, per file, whether
// it is accepted and what is known about it (format, oriented size, EXIF, focal prior).
//
// Bad files do not stop ingest: each gets a reason and the others go on. The report holds
// metadata only; later stages read pixels with ReadImage(record.path, options.reader), so at
// most one decoded image per thread is in memory at any time.
//
// Thread-safety: IngestImages may run concurrently with itself on different inputs; it uses up
// to options.num_threads threads internally (ParallelFor).
#ifndef RECONDUIT_CORE_IMAGE_INGEST_H_
#define RECONDUIT_CORE_IMAGE_INGEST_H_

#include "core/image/image_reader.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"
#include "core/util/status.h"

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

struct IngestOptions {
  // Limits, working size and EXIF switch for every photo (see ImageReaderOptions).
  ImageReaderOptions reader;
  // Threads for inspecting files; 0 = all hardware threads (see EffectiveNumThreads).
  int num_threads = 0;

  // True when valid; otherwise false with a message in *error (which may be null).
  bool Check(std::string* error) const;
};

struct IngestReport {
  // One record per input file, in input order.
  std::vector<ImageRecord> images;
  std::size_t num_accepted = 0;
  std::size_t num_rejected = 0;
  // Wall-clock time of the ingest, in seconds.
  double elapsed_seconds = 0.0;
};

// The files of `directory` to ingest: regular files (symbolic links followed), not recursive,
// hidden files (name starting with '.') skipped, sorted by name (byte order). Nothing is filtered
// by extension: a non-image gets its reason at ingest. NotFound when the directory cannot be read.
Result<std::vector<std::filesystem::path>> ListImageFiles(const std::filesystem::path& directory);

// Inspects every file (InspectImage) in parallel and returns the report in input order.
// Progress: Restart(files.size(), ...), Advance() per file, Finish(). Logs a summary line.
// Throws CanceledError when `cancel` is requested (checked before each file), CheckError when
// the options are invalid.
IngestReport IngestImages(const std::vector<std::filesystem::path>& files,
                          const IngestOptions& options,
                          Progress& progress,
                          const CancelToken& cancel);

// ListImageFiles(directory) followed by IngestImages; NotFound when the directory cannot be read.
Result<IngestReport> IngestDirectory(const std::filesystem::path& directory,
                                     const IngestOptions& options,
                                     Progress& progress,
                                     const CancelToken& cancel);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_INGEST_H_
