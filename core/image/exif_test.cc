#include "core/image/exif.h"

#include "core/image/image_header.h"
#include "core/image/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <optional>
#include <vector>

namespace reconduit {
namespace {

const std::filesystem::path kKermitImages = "../shared/datasets/kermit/images";
const std::filesystem::path kFountainImages = "../shared/datasets/fountain-P11/images";

std::vector<std::uint8_t> ReadFile(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(file), {});
}

std::vector<std::filesystem::path> JpegsIn(const std::filesystem::path& directory) {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(directory)) {
    if (entry.path().extension() == ".jpg") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(ReadExif, KermitPhotosHaveTheSameFocalPrior) {
  if (!std::filesystem::is_directory(kKermitImages)) {
    GTEST_SKIP() << "dataset missing: " << kKermitImages << " (run from the repository root)";
  }
  const std::vector<std::filesystem::path> files = JpegsIn(kKermitImages);
  ASSERT_EQ(files.size(), 11u);
  std::optional<double> first_focal_px;
  for (const std::filesystem::path& file : files) {
    SCOPED_TRACE(file.string());
    const std::vector<std::uint8_t> bytes = ReadFile(file);
    const std::optional<ExifInfo> exif = ReadExif(bytes);
    ASSERT_TRUE(exif.has_value());
    const Result<ImageHeader> header = ReadImageHeader(bytes);
    ASSERT_TRUE(header.ok()) << header.status();
    const std::optional<FocalLengthPixels> focal =
        FocalLengthPixelsFromExif(*exif, header->width, header->height);
    ASSERT_TRUE(focal.has_value());
    std::cout << file.filename().string() << ": " << exif->camera_make << " / "
              << exif->camera_model << ", f = " << exif->focal_length_mm.value_or(-1)
              << " mm, focal plane x res = " << exif->focal_plane_x_resolution.value_or(-1)
              << " (unit " << exif->focal_plane_resolution_unit.value_or(-1) << "), "
              << header->width << "x" << header->height << " -> f = " << focal->focal_px << " px ("
              << FocalSourceName(focal->source) << ")\n";
    EXPECT_EQ(exif->camera_make, "Canon");
    EXPECT_EQ(exif->camera_model, "Canon PowerShot A10");
    ASSERT_TRUE(exif->focal_length_mm.has_value());
    EXPECT_NEAR(*exif->focal_length_mm, 5.406, 1e-3);
    // Dataset notes: 5.406 mm * 3106.8 px/inch / 25.4 mm/inch ~ 661 px for 640x480; Bundler
    // estimated 637-729 px.
    EXPECT_EQ(focal->source, FocalSource::kFocalPlaneResolution);
    EXPECT_GT(focal->focal_px, 600.0);
    EXPECT_LT(focal->focal_px, 730.0);
    if (!first_focal_px) first_focal_px = focal->focal_px;
    EXPECT_NEAR(focal->focal_px, *first_focal_px, 1e-6);
  }
}

TEST(ReadExif, FountainPhotosHaveNoFocalPrior) {
  if (!std::filesystem::is_directory(kFountainImages)) {
    GTEST_SKIP() << "dataset missing: " << kFountainImages << " (run from the repository root)";
  }
  const std::vector<std::filesystem::path> files = JpegsIn(kFountainImages);
  ASSERT_EQ(files.size(), 11u);
  for (const std::filesystem::path& file : files) {
    SCOPED_TRACE(file.string());
    const std::vector<std::uint8_t> bytes = ReadFile(file);
    const std::optional<ExifInfo> exif = ReadExif(bytes);
    if (exif) {
      EXPECT_FALSE(FocalLengthPixelsFromExif(*exif, 3072, 2048).has_value());
    }
  }
}

TEST(ReadExif, GarbageAndImagesWithoutExifGiveNothing) {
  EXPECT_FALSE(ReadExif({}).has_value());
  const std::vector<std::uint8_t> text = {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'g'};
  EXPECT_FALSE(ReadExif(text).has_value());
  const std::vector<std::uint8_t> jpeg =
      testing_util::Encode(testing_util::TestPattern(32, 32), ".jpg");
  EXPECT_FALSE(ReadExif(jpeg).has_value());
  // A JPEG whose APP1 "Exif" segment holds garbage.
  std::vector<std::uint8_t> bad = {0xFF, 0xD8, 0xFF, 0xE1, 0x00, 0x10, 'E',  'x',  'i',  'f', 0,
                                   0,    'M',  'M',  0x00, 0x2A, 0xFF, 0xFF, 0xFF, 0xFF, 1,   2};
  bad.insert(bad.end(), jpeg.begin() + 2, jpeg.end());
  std::optional<ExifInfo> exif;
  EXPECT_NO_THROW(exif = ReadExif(bad));
  EXPECT_FALSE(exif.has_value());
}

TEST(FocalPlaneUnitMillimetres, ExifUnitCodes) {
  EXPECT_DOUBLE_EQ(*FocalPlaneUnitMillimetres(2), 25.4);
  EXPECT_DOUBLE_EQ(*FocalPlaneUnitMillimetres(3), 10.0);
  EXPECT_DOUBLE_EQ(*FocalPlaneUnitMillimetres(4), 1.0);
  EXPECT_DOUBLE_EQ(*FocalPlaneUnitMillimetres(5), 0.001);
  EXPECT_FALSE(FocalPlaneUnitMillimetres(1).has_value());
  EXPECT_FALSE(FocalPlaneUnitMillimetres(0).has_value());
  EXPECT_FALSE(FocalPlaneUnitMillimetres(6).has_value());
}

TEST(FocalLengthPixelsFromExif, ThirtyFiveMillimetreEquivalentUsesLongSide) {
  ExifInfo exif;
  exif.focal_length_35mm = 36.0;
  exif.focal_length_mm = 5.0;  // Ignored: the 35 mm equivalent comes first.
  exif.focal_plane_x_resolution = 1000.0;
  const std::optional<FocalLengthPixels> landscape = FocalLengthPixelsFromExif(exif, 4000, 3000);
  ASSERT_TRUE(landscape.has_value());
  EXPECT_EQ(landscape->source, FocalSource::kFocalLength35mm);
  EXPECT_DOUBLE_EQ(landscape->focal_px, 4000.0);
  // Portrait (after orientation): the same long side, the same focal length.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 3000, 4000)->focal_px, 4000.0);
  exif.focal_length_35mm = 28.0;
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 6000, 4000)->focal_px, 28.0 / 36.0 * 6000.0);
}

TEST(FocalLengthPixelsFromExif, FocalPlaneResolutionUnits) {
  ExifInfo exif;
  exif.focal_length_mm = 5.0;
  exif.focal_plane_x_resolution = 254.0;
  // Unit absent: EXIF's default, inch. 254 px/inch = 10 px/mm.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 640, 480)->focal_px, 50.0);
  exif.focal_plane_resolution_unit = 2;
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 640, 480)->focal_px, 50.0);
  exif.focal_plane_resolution_unit = 3;  // 254 px/cm = 25.4 px/mm.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 640, 480)->focal_px, 127.0);
  exif.focal_plane_resolution_unit = 4;  // 254 px/mm.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 640, 480)->focal_px, 1270.0);
  exif.focal_plane_resolution_unit = 5;  // 254 px/µm = 254000 px/mm.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 640, 480)->focal_px, 1270000.0);
  exif.focal_plane_resolution_unit = 1;  // No absolute unit: unusable.
  EXPECT_FALSE(FocalLengthPixelsFromExif(exif, 640, 480).has_value());
  // Y resolution is used when X is absent.
  exif.focal_plane_resolution_unit = 4;
  exif.focal_plane_x_resolution.reset();
  exif.focal_plane_y_resolution = 100.0;
  const std::optional<FocalLengthPixels> from_y = FocalLengthPixelsFromExif(exif, 640, 480);
  ASSERT_TRUE(from_y.has_value());
  EXPECT_EQ(from_y->source, FocalSource::kFocalPlaneResolution);
  EXPECT_DOUBLE_EQ(from_y->focal_px, 500.0);
}

TEST(FocalLengthPixelsFromExif, ScalesWhenTheImageWasResized) {
  ExifInfo exif;
  exif.focal_length_mm = 4.0;
  exif.focal_plane_x_resolution = 1000.0;
  exif.focal_plane_resolution_unit = 4;  // 1000 px/mm on the 4000 x 3000 original.
  exif.pixel_width = 4000;
  exif.pixel_height = 3000;
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 4000, 3000)->focal_px, 4000.0);
  // Downscaled to half: half the focal length in pixels; portrait orientation changes nothing.
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 2000, 1500)->focal_px, 2000.0);
  EXPECT_DOUBLE_EQ(FocalLengthPixelsFromExif(exif, 1500, 2000)->focal_px, 2000.0);
}

TEST(FocalLengthPixelsFromExif, AbsentWithoutUsableFields) {
  ExifInfo exif;
  EXPECT_FALSE(FocalLengthPixelsFromExif(exif, 640, 480).has_value());
  exif.focal_length_mm = 5.0;  // No sensor information.
  EXPECT_FALSE(FocalLengthPixelsFromExif(exif, 640, 480).has_value());
  exif.focal_length_35mm = 35.0;
  EXPECT_FALSE(FocalLengthPixelsFromExif(exif, 0, 0).has_value());
}

}  // namespace
}  // namespace reconduit
