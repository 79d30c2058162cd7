// Validates one stored upload with core/image's InspectImage and reports what the images table
// needs, in plain values.
// Upload handling (upload.cc) talks to the store; only photo_check.cc depends on core/image.
#ifndef RECONDUIT_SERVER_API_PHOTO_CHECK_H_
#define RECONDUIT_SERVER_API_PHOTO_CHECK_H_

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace reconduit::server {

// The image formats an upload may contain, recognised from a file's first bytes.
enum class PhotoFormat { kUnknown, kJpeg, kPng, kTiff };

// How many leading bytes DetectPhotoFormat needs.
std::size_t PhotoFormatMagicBytes();
// JPEG, PNG or TIFF by signature (core/image/image_format.h); kUnknown otherwise or when fewer
// bytes than a signature are given.
PhotoFormat DetectPhotoFormat(std::string_view first_bytes);
// The extension stored photos get: "jpg", "png", "tif"; "" for kUnknown.
std::string_view PhotoFormatExtension(PhotoFormat format);

struct PhotoCheckOptions {
  // Shortest accepted side in pixels (the job's min_image_side option).
  int min_side = 100;
  // Largest accepted width * height, checked from the header before decoding.
  std::int64_t max_pixels = 100'000'000;
  // Largest accepted file; larger files are rejected without being read.
  std::int64_t max_file_bytes = std::int64_t{256} << 20;
};

// The verdict on one photo.
struct PhotoCheck {
  bool accepted = false;
  // Why it was rejected, without the file name ("truncated: the JPEG data ends before ...").
  std::string reason;
  std::int64_t bytes = 0;
  // As displayed (after EXIF orientation); set when the header could be read.
  std::optional<int> width;
  std::optional<int> height;
  // Focal length prior in pixels from EXIF, when present.
  std::optional<double> exif_focal_px;
  std::string make;
  std::string model;
};

// Inspects the photo at `path`: header limits, truncation, a full decode, EXIF. Never throws
// for a bad file. Thread-safe.
PhotoCheck CheckPhoto(const std::filesystem::path& path, const PhotoCheckOptions& options);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_API_PHOTO_CHECK_H_
