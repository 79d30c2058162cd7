// Reading one photo: validation with per-file reasons, EXIF, decoding and orientation.
//
// InspectImage checks a file the way ingest needs: it refuses what is not a JPEG, PNG or TIFF
// (by content, never by name), what is too large (file bytes, or pixels declared by the header,
// checked before anything is decoded, so a decompression bomb costs nothing), too small,
// truncated (see CheckImageComplete) or undecodable, and returns the metadata of the rest.
// It decodes the pixels to prove they decode, then drops them. ReadImage runs the same checks
// and returns the pixels for later stages.
//
// Orientation: pixels are decoded as stored and rotated/flipped here by the EXIF orientation
// tag (read with exiv2 for all three formats), so the sizes, the focal prior and the pixels
// always agree: width and height are as displayed.
//
// Failures are values: a non-OK Status whose message names the file, e.g.
//   "IMG_1.jpg: truncated: the JPEG data ends before its end-of-image marker".
// Codes: NotFound (cannot open), ResourceExhausted (over a size limit), InvalidArgument
// (everything else that is wrong with the file).
//
// Thread-safety: all functions may be called concurrently on different files.
#ifndef RECONDUIT_CORE_IMAGE_IMAGE_READER_H_
#define RECONDUIT_CORE_IMAGE_IMAGE_READER_H_

#include "core/image/exif.h"
#include "core/image/image_format.h"
#include "core/util/status.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

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
};

// Validates and describes one file, decoding it once to prove it decodes. Never throws for a
// bad file; throws CheckError when the options are invalid.
ImageRecord InspectImage(const std::filesystem::path& path, const ImageReaderOptions& options);

// Reads one photo as 8-bit, 3-channel BGR (grey and 16-bit images are converted, alpha is
// dropped), oriented by its EXIF tag and downscaled to options.max_side when set. Refuses the
// same files as InspectImage, with the same reasons. Throws CheckError on invalid options.
Result<cv::Mat> ReadImage(const std::filesystem::path& path, const ImageReaderOptions& options);

// Returns `image` rotated/flipped so that a stored image with EXIF orientation `orientation`
// (1..8) appears upright. Orientations 5..8 swap width and height. Out-of-range values are
// treated as 1. The result may share data with `image` when no change is needed.
cv::Mat ApplyExifOrientation(const cv::Mat& image, int orientation);

// The size (width, height) of an image of `width` x `height` downscaled so that its long side
// is at most max_side (aspect ratio kept, each side at least 1); unchanged when max_side <= 0
// or the image already fits.
cv::Size WorkingSize(int width, int height, int max_side);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_IMAGE_READER_H_
