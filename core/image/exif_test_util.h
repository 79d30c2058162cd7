// Test helper (header-only; tests that include it link exiv2): JPEG files with EXIF tags.
#ifndef RECONDUIT_CORE_IMAGE_EXIF_TEST_UTIL_H_
#define RECONDUIT_CORE_IMAGE_EXIF_TEST_UTIL_H_

#include "core/image/test_util.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <vector>

// exiv2 0.27's public API is built on std::auto_ptr, deprecated since C++11.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>

namespace reconduit::testing_util {

// Writes JPEG bytes at `path` with Exif.Image.Orientation, Make "Reconduit", Model "Test 1"
// and a 24 mm focal length in 35 mm terms.
inline void WriteJpegWithExif(const std::filesystem::path& path,
                              const std::vector<std::uint8_t>& jpeg,
                              int orientation) {
  WriteBytes(path, jpeg);
  Exiv2::Image::AutoPtr image = Exiv2::ImageFactory::open(path.string());
  ASSERT_NE(image.get(), nullptr);
  image->readMetadata();
  Exiv2::ExifData exif;
  exif["Exif.Image.Orientation"] = static_cast<std::uint16_t>(orientation);
  exif["Exif.Image.Make"] = "Reconduit";
  exif["Exif.Image.Model"] = "Test 1";
  exif["Exif.Photo.FocalLengthIn35mmFilm"] = static_cast<std::uint16_t>(24);
  image->setExifData(exif);
  image->writeMetadata();
}

}  // namespace reconduit::testing_util

#pragma GCC diagnostic pop

#endif  // RECONDUIT_CORE_IMAGE_EXIF_TEST_UTIL_H_
