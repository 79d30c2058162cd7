// EXIF (core/image/exif.h, through exiv2) of an uploaded photo, and the focal length prior
// derived from it: never throws, and a prior, when there is one, is a finite positive number.
#include "core/image/exif.h"

#include "fuzz/fuzz_util.h"
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

using namespace reconduit;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::optional<ExifInfo> exif = ReadExif(std::span<const std::uint8_t>(data, size));
  if (!exif) return 0;
  if (exif->orientation) RECONDUIT_FUZZ_CHECK(*exif->orientation >= 1 && *exif->orientation <= 8);
  for (const auto& value : {exif->focal_length_mm, exif->focal_length_35mm,
                            exif->focal_plane_x_resolution, exif->focal_plane_y_resolution}) {
    if (value) RECONDUIT_FUZZ_CHECK(std::isfinite(*value) && *value > 0);
  }
  for (const auto& [width, height] : {std::pair{4000, 3000}, std::pair{1, 100000}}) {
    if (const auto focal = FocalLengthPixelsFromExif(*exif, width, height)) {
      RECONDUIT_FUZZ_CHECK(std::isfinite(focal->focal_px) && focal->focal_px > 0);
    }
  }
  return 0;
}
