// Checking one photo without decoding its pixels: what the upload server can afford on an HTTP
// I/O thread, and the first half of what ingest does before it decodes.
//
// InspectImageHeader refuses what is not a JPEG, PNG or TIFF (by content, never by name), what
// is too large (file bytes, or pixels declared by the header, so a decompression bomb costs
// nothing), too small or truncated (see CheckImageComplete), and returns the metadata of the
// rest: format, size as displayed (after the EXIF orientation), EXIF fields and focal prior.
// It never decodes pixels, so a photo whose header and end marker are intact but whose
// compressed data is corrupt in the middle passes here; InspectImage and ReadImage
// (image_reader.h, which decode) refuse it with a per-file reason at ingest.
//
// This part of core/image is its own library, reconduit_image_header (format, header, EXIF:
// exiv2, no OpenCV), so the server links it without the codecs.
//
// Failures are values: a non-OK Status whose message names the file, e.g.
//   "IMG_1.jpg: truncated: the JPEG data ends before its end-of-image marker".
// Codes: NotFound (cannot open), ResourceExhausted (over a size limit), InvalidArgument
// (everything else that is wrong with the file).
//
// Thread-safety: all functions may be called concurrently on different files.
#ifndef RECONDUIT_CORE_IMAGE_IMAGE_CHECK_H_
#define RECONDUIT_CORE_IMAGE_IMAGE_CHECK_H_

#include "core/image/exif.h"
#include "core/image/image_format.h"
#include "core/image/photo_metadata.h"
#include "core/util/status.h"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace reconduit {

struct ImageReaderOptions {
  // Smallest accepted width and height in pixels, >= 1.
  int min_side = 100;
  // Largest accepted width * height in pixels, >= min_side^2. Checked from the header before
  // decoding. 100 MP leaves room for today's largest phone and DSLR photos.
  std::int64_t max_pixels = 100'000'000;
  // Largest accepted file size in bytes, >= 1. Files are read into memory whole.
  std::int64_t max_file_bytes = std::int64_t{256} << 20;
  // Working resolution: when > 0, ReadImage downscales (INTER_AREA) so that the long side is
  // at most max_side pixels; it never upscales. 0 keeps the full resolution.
  int max_side = 0;
  // Whether to report EXIF fields and the focal prior. EXIF orientation is applied either way.
  bool read_exif = true;
  // Whether ReadImage gives one grey channel instead of BGR (what features need: a third of
  // the memory of a large PNG or TIFF, which cannot be decoded at reduced size).
  bool grey = false;

  // True when every field is in range; otherwise false with a message in *error (which may be
  // null), e.g. "min_side = 0; it must be at least 1".
  bool Check(std::string* error) const;
};

// What is known about one photo.
struct ImageInfo {
  ImageFormat format = ImageFormat::kUnknown;
  std::int64_t file_bytes = 0;
  // Size in pixels as displayed, i.e. after EXIF orientation.
  int width = 0;
  int height = 0;
  // EXIF orientation applied to the stored pixels (1..8; 1 = none).
  int orientation = 1;
  // Size ReadImage returns with the same options (equal to width/height unless max_side
  // downscales). Scale focal_px by working_width / width for the working image.
  int working_width = 0;
  int working_height = 0;
  // EXIF fields; absent when the file has none, it is unreadable or read_exif is false.
  std::optional<ExifInfo> exif;
  // Focal length prior in pixels of the width x height image, and its source.
  std::optional<FocalLengthPixels> focal;
};

// The outcome for one file.
struct ImageRecord {
  // The file's name without its directory (display only).
  std::string name;
  std::filesystem::path path;
  // OK when the photo is accepted; otherwise why it was refused.
  Status status;
  // Filled as far as the inspection got (format and file_bytes even for most refusals).
  ImageInfo info;

  bool accepted() const { return status.ok(); }
  // The refusal reason without the leading "<name>: " (empty when accepted), for callers that
  // show it next to a name of their own.
  std::string ReasonWithoutName() const;
  // The photo facts later readers keep (photo_metadata.h): bytes, displayed size (0 x 0 unless
  // both sides are known), EXIF focal prior and its source, make, model, and acceptance with
  // ReasonWithoutName. The one conversion used by ingest and the upload check.
  PhotoMetadata Metadata() const;
};

// Validates and describes one file from its bytes, without decoding pixels (see the file
// comment). When `bytes` is non-null and the photo is accepted, it receives the whole file so
// that a decoder need not read it again. Never throws for a bad file; throws CheckError when
// the options are invalid.
ImageRecord InspectImageHeader(const std::filesystem::path& path,
                               const ImageReaderOptions& options,
                               std::vector<std::uint8_t>* bytes = nullptr);

// The size (width, height) of an image of `width` x `height` downscaled so that its long side
// is at most max_side (aspect ratio kept, each side at least 1); unchanged when max_side <= 0
// or the image already fits.
std::pair<int, int> WorkingSideLengths(int width, int height, int max_side);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_IMAGE_CHECK_H_
