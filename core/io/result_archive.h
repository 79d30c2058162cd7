// The result archive: every file of an output folder, plus a manifest, in one zip.
//
// manifest.json lists each file (forward-slash path relative to the folder), its size in
// bytes and its SHA-256, sorted by path, so a client can verify a download file by file.
// The manifest is written into the folder too, so the folder and the zip hold the same files.
// The zip is written to "<zip>.tmp", fsynced and renamed: a crash leaves either no archive or
// a complete one.
#ifndef RECONDUIT_CORE_IO_RESULT_ARCHIVE_H_
#define RECONDUIT_CORE_IO_RESULT_ARCHIVE_H_

#include "core/util/cancel.h"
#include "core/util/status.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

struct ManifestEntry {
  std::string name;  // Path inside the archive, '/'-separated.
  std::int64_t bytes = 0;
  std::string sha256;  // Lower-case hex.
};

struct ResultArchiveSummary {
  std::vector<ManifestEntry> files;  // Including manifest.json itself (last).
  std::int64_t archive_bytes = 0;
  std::string archive_sha256;
};

// Writes `folder`/manifest.json and packs the folder into `zip_path` atomically.
// Large already-compressed files (JPEG, PNG, GLB) are stored, others deflated.
Result<ResultArchiveSummary> WriteResultArchive(const std::filesystem::path& folder,
                                                const std::filesystem::path& zip_path,
                                                const CancelToken& cancel);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_RESULT_ARCHIVE_H_
