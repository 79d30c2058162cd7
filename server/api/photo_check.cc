#include "server/api/photo_check.h"

#include "core/image/image_check.h"

#include <algorithm>
#include <climits>
#include <cstdint>

namespace reconduit::server {

PhotoMetadata CheckPhoto(const std::filesystem::path& path, const PhotoCheckOptions& options) {
  ImageReaderOptions reader;
  reader.min_side = std::max(1, options.min_side);
  reader.max_pixels =
      std::max<std::int64_t>(options.max_pixels, std::int64_t{reader.min_side} * reader.min_side);
  // ImageReaderOptions reads files whole and caps them at INT_MAX bytes.
  reader.max_file_bytes = std::clamp<std::int64_t>(options.max_file_bytes, 1, INT_MAX);
  reader.read_exif = true;
  // The reason leaves out the stored name ("0003.jpg"), which means nothing to the client, who
  // sees it next to its own file name.
  return InspectImageHeader(path, reader).Metadata();
}

}  // namespace reconduit::server
