#include "core/image/image_format.h"

#include "core/image/test_util.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {
namespace {

std::vector<std::uint8_t> Bytes(std::initializer_list<int> values) {
  std::vector<std::uint8_t> bytes;
  for (int v : values) bytes.push_back(static_cast<std::uint8_t>(v));
  return bytes;
}

TEST(DetectImageFormat, RecognisesSignatures) {
  EXPECT_EQ(DetectImageFormat(Bytes({0xFF, 0xD8, 0xFF, 0xE0})), ImageFormat::kJpeg);
  EXPECT_EQ(DetectImageFormat(Bytes({0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A})),
            ImageFormat::kPng);
  EXPECT_EQ(DetectImageFormat(Bytes({'I', 'I', 42, 0, 8, 0, 0, 0})), ImageFormat::kTiff);
  EXPECT_EQ(DetectImageFormat(Bytes({'M', 'M', 0, 42, 0, 0, 0, 8})), ImageFormat::kTiff);
}

TEST(DetectImageFormat, RejectsNonImagesAndShortInput) {
  EXPECT_EQ(DetectImageFormat({}), ImageFormat::kUnknown);
  EXPECT_EQ(DetectImageFormat(Bytes({0xFF, 0xD8})), ImageFormat::kUnknown);
  // A PNG signature with a damaged line-ending byte (as after a text-mode transfer).
  EXPECT_EQ(DetectImageFormat(Bytes({0x89, 'P', 'N', 'G', 0x0A, 0x1A, 0x0A, 0x00})),
            ImageFormat::kUnknown);
  const std::string text = "hello, world";
  EXPECT_EQ(DetectImageFormat(std::span<const std::uint8_t>(
                reinterpret_cast<const std::uint8_t*>(text.data()), text.size())),
            ImageFormat::kUnknown);
  // Mixed byte order marks and BigTIFF are not classic TIFF.
  EXPECT_EQ(DetectImageFormat(Bytes({'I', 'I', 0, 42})), ImageFormat::kUnknown);
  EXPECT_EQ(DetectImageFormat(Bytes({'I', 'I', 43, 0, 8, 0, 0, 0})), ImageFormat::kUnknown);
}

TEST(DetectImageFormat, EncodedImagesAreRecognised) {
  const cv::Mat image = testing_util::TestPattern(16, 8);
  EXPECT_EQ(DetectImageFormat(testing_util::Encode(image, ".jpg")), ImageFormat::kJpeg);
  EXPECT_EQ(DetectImageFormat(testing_util::Encode(image, ".png")), ImageFormat::kPng);
  EXPECT_EQ(DetectImageFormat(testing_util::Encode(image, ".tif")), ImageFormat::kTiff);
}

TEST(DetectImageFormatOfFile, UsesContentNotName) {
  const testing_util::ScopedTempDir dir;
  testing_util::WriteBytes(dir / "photo.jpg",
                           testing_util::Encode(testing_util::TestPattern(16, 8), ".png"));
  testing_util::WriteText(dir / "notes.png", "not an image\n");
  testing_util::WriteText(dir / "empty.jpg", "");

  const Result<ImageFormat> png = DetectImageFormatOfFile(dir / "photo.jpg");
  ASSERT_TRUE(png.ok()) << png.status();
  EXPECT_EQ(*png, ImageFormat::kPng);
  EXPECT_EQ(*DetectImageFormatOfFile(dir / "notes.png"), ImageFormat::kUnknown);
  EXPECT_EQ(*DetectImageFormatOfFile(dir / "empty.jpg"), ImageFormat::kUnknown);
  EXPECT_EQ(DetectImageFormatOfFile(dir / "missing.jpg").status().code(), StatusCode::kNotFound);
}

TEST(ImageFormatName, NamesAndMimeTypes) {
  EXPECT_EQ(ImageFormatName(ImageFormat::kJpeg), "JPEG");
  EXPECT_EQ(ImageFormatName(ImageFormat::kUnknown), "unknown");
  EXPECT_EQ(ImageFormatMimeType(ImageFormat::kPng), "image/png");
  EXPECT_EQ(ImageFormatMimeType(ImageFormat::kTiff), "image/tiff");
  EXPECT_EQ(ImageFormatMimeType(ImageFormat::kUnknown), "application/octet-stream");
}

TEST(ImageFormatExtension, ExtensionsOfStoredPhotos) {
  EXPECT_EQ(ImageFormatExtension(ImageFormat::kJpeg), "jpg");
  EXPECT_EQ(ImageFormatExtension(ImageFormat::kPng), "png");
  EXPECT_EQ(ImageFormatExtension(ImageFormat::kTiff), "tif");
  EXPECT_EQ(ImageFormatExtension(ImageFormat::kUnknown), "");
}

}  // namespace
}  // namespace reconduit
