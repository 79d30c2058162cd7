// The result archive: every file of an output folder, plus a manifest, in one zip.
//
// manifest.json lists each file in the zip (forward-slash path relative to the folder), its size in
// bytes and its SHA-256, sorted by path, so a client can verify a download file by file.
// The manifest is written into the folder too, so the folder and the zip hold the same files,
// unless the caller leaves some out of the zip (ArchiveExclusions).
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

// What to leave out of the archive: each entry is a file ("dense.ply") or, ending in '/', a
// folder and everything under it ("depth/"), relative to the folder, '/'-separated. Left-out
// files stay in the folder but are neither in the zip nor in the manifest.
using ArchiveExclusions = std::vector<std::string>;

// The files WriteResultArchive packs, sorted by name ('/'-separated, relative to `folder`):
// every regular file of the folder (no symlinks) that `excluded` does not name, without
// manifest.json (which the archive adds last). NotFound when the folder does not exist.
Result<std::vector<std::string>> ListResultFiles(const std::filesystem::path& folder,
                                                 const ArchiveExclusions& excluded = {});

// Writes `folder`/manifest.json and packs the folder, less `excluded`, into `zip_path`
// atomically. Large already-compressed files (JPEG, PNG, GLB) are stored, others deflated.
Result<ResultArchiveSummary> WriteResultArchive(const std::filesystem::path& folder,
                                                const std::filesystem::path& zip_path,
                                                const CancelToken& cancel,
                                                const ArchiveExclusions& excluded = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_RESULT_ARCHIVE_H_
