#include "server/api/photo_check.h"

#include "core/image/image_format.h"
#include "core/image/image_reader.h"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <span>

namespace reconduit::server {

std::size_t PhotoFormatMagicBytes() { return kImageFormatMagicBytes; }

PhotoFormat DetectPhotoFormat(std::string_view first_bytes) {
  const std::span<const std::uint8_t> bytes(
      reinterpret_cast<const std::uint8_t*>(first_bytes.data()), first_bytes.size());
  switch (DetectImageFormat(bytes)) {
    case ImageFormat::kJpeg:
      return PhotoFormat::kJpeg;
    case ImageFormat::kPng:
      return PhotoFormat::kPng;
    case ImageFormat::kTiff:
      return PhotoFormat::kTiff;
    case ImageFormat::kUnknown:
      break;
  }
  return PhotoFormat::kUnknown;
}

std::string_view PhotoFormatExtension(PhotoFormat format) {
  switch (format) {
    case PhotoFormat::kJpeg:
      return "jpg";
    case PhotoFormat::kPng:
      return "png";
    case PhotoFormat::kTiff:
      return "tif";
    case PhotoFormat::kUnknown:
      break;
  }
  return "";
}

PhotoCheck CheckPhoto(const std::filesystem::path& path, const PhotoCheckOptions& options) {
  ImageReaderOptions reader;
  reader.min_side = std::max(1, options.min_side);
  reader.max_pixels =
      std::max<std::int64_t>(options.max_pixels, std::int64_t{reader.min_side} * reader.min_side);
  // ImageReaderOptions reads files whole and caps them at INT_MAX bytes.
  reader.max_file_bytes = std::clamp<std::int64_t>(options.max_file_bytes, 1, INT_MAX);
  reader.read_exif = true;

  const ImageRecord record = InspectImage(path, reader);
  PhotoCheck check;
  check.accepted = record.accepted();
  check.bytes = record.info.file_bytes;
  if (record.info.width > 0 && record.info.height > 0) {
    check.width = record.info.width;
    check.height = record.info.height;
  }
  if (record.info.focal) check.exif_focal_px = record.info.focal->focal_px;
  if (record.info.exif) {
    check.make = record.info.exif->camera_make;
    check.model = record.info.exif->camera_model;
  }
  if (!check.accepted) {
    // The message starts with the file name ("0003.jpg: truncated: ..."); the stored name means
    // nothing to the client, who sees the reason next to its own file name.
    std::string reason = record.status.message();
    const std::string prefix = path.filename().string() + ": ";
    if (reason.rfind(prefix, 0) == 0) reason.erase(0, prefix.size());
    check.reason = reason.empty() ? "rejected" : reason;
  }
  return check;
}

}  // namespace reconduit::server
