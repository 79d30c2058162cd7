// Reading photos out of an uploaded zip archive (POST /api/v1/jobs with Content-Type
// application/zip), defensively.
//
// Everything about the archive is checked from its central directory before a single byte is
// extracted, and the whole archive is refused on the first problem:
//   * entry names: every entry (also skipped ones) must be a safe relative path
//     (CheckRelativePath: no "..", no absolute path, no drive letter, no '\');
//   * entry types: symbolic links and other special files (Unix mode in the external
//     attributes) are refused; directories are skipped;
//   * encrypted entries are refused;
//   * decompression bombs: the number of entries, each photo's declared size, the sum of the
//     declared sizes, each photo's compression ratio (over ratio_min_bytes) and the ratio of
//     the whole archive (declared over compressed sizes of all photos, once they sum to more
//     than ratio_min_bytes: many small entries of zeros are a bomb too) are limited. Photos
//     barely compress (JPEG, PNG and most TIFFs are compressed already), so a high ratio means
//     a bomb.
// While extracting, bytes are counted: an entry that produces more than its declared size is
// refused, and so is an archive whose entries together produce more than max_total_bytes, so
// a lying central directory cannot get past the limits either.
//
// Skipped (listed in skipped(), except directories): directory entries, macOS metadata
// ("__MACOSX/..."), hidden files (base name starting with '.', such as ".DS_Store" or
// "._IMG_1.jpg"), Windows' "Thumbs.db" and "desktop.ini", and nested archives ("*.zip"):
// what real zips from Windows and macOS carry.
//
// Errors: kInvalidArgument (not a zip, corrupt, unsafe entry, encrypted), kResourceExhausted
// (a size limit; the upload answers 413). Messages name the entry.
//
// Not thread-safe; one archive per upload.
#ifndef RECONDUIT_SERVER_API_ZIP_READER_H_
#define RECONDUIT_SERVER_API_ZIP_READER_H_

#include "core/util/status.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit::server {

struct ZipLimits {
  // Entries in the central directory, counting directories and skipped files.
  std::int64_t max_entries = 20000;
  // Photo entries (after skipping).
  std::int64_t max_photos = 1000;
  // Largest declared size of one photo, in bytes.
  std::uint64_t max_entry_bytes = std::uint64_t{256} << 20;
  // Largest sum of the photos' declared sizes, in bytes.
  std::uint64_t max_total_bytes = std::uint64_t{4} << 30;
  // Largest uncompressed / compressed size of a photo, checked for photos over
  // ratio_min_bytes (tiny files may legitimately compress well).
  double max_ratio = 100.0;
  std::uint64_t ratio_min_bytes = 1 << 20;
};

// A photo inside the archive.
struct ZipPhotoEntry {
  std::uint64_t index = 0;  // Position in the archive.
  std::string name;         // The entry's name as stored (validated relative path).
  std::uint64_t size = 0;   // Declared uncompressed size.
};

class ZipPhotoArchive {
 public:
  // Opens the archive and checks every entry against `limits` (see above).
  static Result<std::unique_ptr<ZipPhotoArchive>> Open(const std::filesystem::path& path,
                                                       const ZipLimits& limits);
  ~ZipPhotoArchive();
  ZipPhotoArchive(const ZipPhotoArchive&) = delete;
  ZipPhotoArchive& operator=(const ZipPhotoArchive&) = delete;

  // The photo entries in archive order.
  const std::vector<ZipPhotoEntry>& photos() const { return photos_; }
  // The names of the files that were skipped (not directories), in archive order.
  const std::vector<std::string>& skipped() const { return skipped_; }

  // Decompresses one entry, passing its bytes to `sink` in pieces of at most 64 KiB; stops at
  // the first non-OK Status from the sink and returns it. kResourceExhausted when the entry
  // produces more than its declared size, kInvalidArgument when it is corrupt (CRC, truncated).
  Status Extract(const ZipPhotoEntry& entry,
                 const std::function<Status(std::string_view data)>& sink);

 private:
  struct Handle;
  explicit ZipPhotoArchive(std::unique_ptr<Handle> handle);

  std::unique_ptr<Handle> handle_;
  std::vector<ZipPhotoEntry> photos_;
  std::vector<std::string> skipped_;
  std::uint64_t max_total_bytes_ = 0;
  std::uint64_t extracted_ = 0;  // Bytes produced by Extract so far, all entries.
};

// True for entries the archive skips: directories, "__MACOSX/...", hidden base names,
// Thumbs.db, desktop.ini and nested "*.zip" archives (names compared case-insensitively).
bool IsSkippedZipEntry(std::string_view name);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_ZIP_READER_H_
