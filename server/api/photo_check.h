// Checks one stored upload on the HTTP I/O thread and returns the metadata of its images row.
//
// Header checks only (core/image/image_check.h): format by content, size limits from the
// header, truncation (a missing end-of-image marker or a short chunk), EXIF make, model and
// focal prior. Pixels are never decoded here: decoding a 100-megapixel photo takes a second and
// would block every other request served by this I/O thread. The ingest stage decodes every
// photo anyway and refuses one whose compressed data is corrupt, with a per-image reason in
// the job's report; such a photo is accepted at upload.
// Upload handling (upload.cc) talks to the store and detects the type by the first bytes
// (core/image/image_format.h); the header checks are here.
#ifndef RECONDUIT_SERVER_API_PHOTO_CHECK_H_
#define RECONDUIT_SERVER_API_PHOTO_CHECK_H_

#include "core/image/photo_metadata.h"

#include <cstdint>
#include <filesystem>

namespace reconduit::server {

struct PhotoCheckOptions {
  // Shortest accepted side in pixels (the job's min_image_side option).
  int min_side = 100;
  // Largest accepted width * height, checked from the header.
  std::int64_t max_pixels = 100'000'000;
  // Largest accepted file; larger files are rejected without being read.
  std::int64_t max_file_bytes = std::int64_t{256} << 20;
};

// Inspects the photo at `path` (header checks only, see above) and returns its metadata for
// the images row: bytes, width and height as displayed (0 when the header could not be read),
// EXIF focal prior, make and model, acceptance and the refusal reason (without the file name).
// Never throws for a bad file. Thread-safe.
PhotoMetadata CheckPhoto(const std::filesystem::path& path, const PhotoCheckOptions& options);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_PHOTO_CHECK_H_
