#include "server/api/photo_check.h"

#include "core/image/image_check.h"

#include <algorithm>
#include <climits>
#include <cstdint>

namespace reconduit::server {

void CheckPhoto(const std::filesystem::path& path,
                const PhotoCheckOptions& options,
                JobImageRecord* record) {
  ImageReaderOptions reader;
  reader.min_side = std::max(1, options.min_side);
  reader.max_pixels =
      std::max<std::int64_t>(options.max_pixels, std::int64_t{reader.min_side} * reader.min_side);
  // ImageReaderOptions reads files whole and caps them at INT_MAX bytes.
  reader.max_file_bytes = std::clamp<std::int64_t>(options.max_file_bytes, 1, INT_MAX);
  reader.read_exif = true;

  const ImageRecord image = InspectImageHeader(path, reader);
  record->bytes = image.info.file_bytes;
  record->width.reset();
  record->height.reset();
  if (image.info.width > 0 && image.info.height > 0) {
    record->width = image.info.width;
    record->height = image.info.height;
  }
  record->exif_focal_px.reset();
  if (image.info.focal) record->exif_focal_px = image.info.focal->focal_px;
  record->make = image.info.exif ? image.info.exif->camera_make : "";
  record->model = image.info.exif ? image.info.exif->camera_model : "";
  record->status = image.accepted() ? ImageStatus::kAccepted : ImageStatus::kRejected;
  // The stored name ("0003.jpg") means nothing to the client, who sees the reason next to its
  // own file name.
  record->reject_reason = image.ReasonWithoutName();
}

}  // namespace reconduit::server
