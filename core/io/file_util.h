// Crash-safe file writing and hashing.
//
// Results are what users download, so a crash must never leave a half-written file under its
// final name: WriteFileAtomically writes to a temporary name in the same folder, fsyncs it,
// renames it over the target and fsyncs the folder, so a reader sees the old file or the whole
// new one.
#ifndef RECONDUIT_CORE_IO_FILE_UTIL_H_
#define RECONDUIT_CORE_IO_FILE_UTIL_H_

#include "core/util/status.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace reconduit {

// Writes `contents` to `path` atomically (temp file, fsync, rename, fsync of the folder).
Status WriteFileAtomically(const std::filesystem::path& path, std::string_view contents);

// Renames `from` to `to` (same file system) and fsyncs `from` before and the folder after.
Status CommitFile(const std::filesystem::path& from, const std::filesystem::path& to);

// fsync on a file or a folder.
Status SyncPath(const std::filesystem::path& path);

// The whole file, or NotFound / Internal.
Result<std::string> ReadFile(const std::filesystem::path& path);

// Lower-case hex SHA-256 of a file's bytes (streamed; OpenSSL's EVP interface).
Result<std::string> Sha256OfFile(const std::filesystem::path& path);
// Lower-case hex SHA-256 of a buffer.
std::string Sha256Hex(std::string_view bytes);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_FILE_UTIL_H_
