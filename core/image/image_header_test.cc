#include "core/image/image_header.h"

#include "core/image/test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

std::vector<std::uint8_t> Prefix(const std::vector<std::uint8_t>& bytes, std::size_t size) {
  return std::vector<std::uint8_t>(bytes.begin(), bytes.begin() + size);
}

TEST(ReadImageHeader, SizeOfEncodedImages) {
  const cv::Mat image = testing_util::TestPattern(123, 45);
  for (const char* extension : {".jpg", ".png", ".tif"}) {
    SCOPED_TRACE(extension);
    const std::vector<std::uint8_t> bytes = testing_util::Encode(image, extension);
    ASSERT_FALSE(bytes.empty());
    const Result<ImageHeader> header = ReadImageHeader(bytes);
    ASSERT_TRUE(header.ok()) << header.status();
    EXPECT_EQ(header->width, 123);
    EXPECT_EQ(header->height, 45);
  }
}

TEST(ReadImageHeader, BigEndianTiff) {
  // Hand-made big-endian TIFF: IFD0 at 8 with ImageWidth = 70000 (LONG), ImageLength = 300
  // (SHORT), then the next-IFD offset.
  const std::vector<std::uint8_t> bytes = {
      'M', 'M', 0, 42, 0, 0, 0, 8,                       // Header.
      0,   2,                                            // 2 entries.
      1,   0,   0, 4,  0, 0, 0, 1, 0, 1,    0x11, 0x70,  // 256.
      1,   1,   0, 3,  0, 0, 0, 1, 1, 0x2C, 0,    0,     // 257.
      0,   0,   0, 0};
  const Result<ImageHeader> header = ReadImageHeader(bytes);
  ASSERT_TRUE(header.ok()) << header.status();
  EXPECT_EQ(header->format, ImageFormat::kTiff);
  EXPECT_EQ(header->width, 70000);
  EXPECT_EQ(header->height, 300);
  // No strips: the header is readable but the file holds no image data.
  EXPECT_THAT(CheckImageComplete(bytes).message(), HasSubstr("no image data"));
}

TEST(ReadImageHeader, JpegPrefixUpToFrameHeaderSuffices) {
  const std::vector<std::uint8_t> bytes =
      testing_util::Encode(testing_util::TestPattern(64, 32), ".jpg");
  // OpenCV writes SOI, APP0 (JFIF), DQT, SOF0 near the start: 1 KiB is plenty.
  const Result<ImageHeader> header = ReadImageHeader(Prefix(bytes, 1024));
  ASSERT_TRUE(header.ok()) << header.status();
  EXPECT_EQ(header->width, 64);
  EXPECT_EQ(header->height, 32);
  EXPECT_FALSE(ReadImageHeader(Prefix(bytes, 10)).ok());
}

TEST(ReadImageHeader, DecompressionBombHeaderIsParsed) {
  const Result<ImageHeader> header = ReadImageHeader(testing_util::PngHeaderOnly(100000, 100000));
  ASSERT_TRUE(header.ok()) << header.status();
  EXPECT_EQ(header->width, 100000);
  EXPECT_EQ(header->height, 100000);
}

TEST(ReadImageHeader, RejectsUnknownAndZeroSize) {
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', '!', '!', '!'};
  EXPECT_THAT(ReadImageHeader(text).status().message(), HasSubstr("not a JPEG, PNG or TIFF"));
  EXPECT_THAT(ReadImageHeader(testing_util::PngHeaderOnly(0, 10)).status().message(),
              HasSubstr("invalid size of 0x10"));
}

TEST(CheckImageComplete, AcceptsCompleteFiles) {
  const cv::Mat image = testing_util::TestPattern(200, 150);
  for (const char* extension : {".jpg", ".png", ".tif"}) {
    SCOPED_TRACE(extension);
    EXPECT_TRUE(CheckImageComplete(testing_util::Encode(image, extension)).ok());
  }
}

TEST(CheckImageComplete, DetectsTruncation) {
  const cv::Mat image = testing_util::TestPattern(200, 150);
  const std::vector<std::uint8_t> jpeg = testing_util::Encode(image, ".jpg");
  const std::vector<std::uint8_t> png = testing_util::Encode(image, ".png");
  const std::vector<std::uint8_t> tiff = testing_util::Encode(image, ".tif");
  EXPECT_THAT(CheckImageComplete(Prefix(jpeg, jpeg.size() / 2)).message(),
              HasSubstr("truncated: the JPEG data ends before its end-of-image marker"));
  // Only the final EOI missing.
  EXPECT_THAT(CheckImageComplete(Prefix(jpeg, jpeg.size() - 2)).message(), HasSubstr("truncated"));
  EXPECT_THAT(CheckImageComplete(Prefix(png, png.size() / 2)).message(), HasSubstr("truncated"));
  // Only the 12-byte IEND chunk missing.
  EXPECT_THAT(CheckImageComplete(Prefix(png, png.size() - 12)).message(),
              HasSubstr("truncated: the PNG data ends before its IEND chunk"));
  // A TIFF cut short: the directory (written at the end by libtiff) is gone.
  EXPECT_THAT(CheckImageComplete(Prefix(tiff, tiff.size() / 2)).message(), HasSubstr("truncated"));
}

// Little-endian TIFF with IFD0 at 8: 16 x 16 pixels in one strip at `strip_offset` of
// `strip_bytes` bytes, padded to `file_bytes`.
std::vector<std::uint8_t> HandMadeTiff(std::uint32_t strip_offset,
                                       std::uint32_t strip_bytes,
                                       std::size_t file_bytes) {
  std::vector<std::uint8_t> bytes = {'I', 'I', 42, 0, 8, 0, 0, 0, 4, 0};
  const auto entry = [&bytes](std::uint16_t tag, std::uint16_t type, std::uint32_t value) {
    for (std::uint32_t v : {std::uint32_t{tag}, std::uint32_t{type}}) {
      bytes.push_back(v & 0xFF);
      bytes.push_back(v >> 8);
    }
    for (std::uint32_t v : {std::uint32_t{1}, value}) {
      for (int shift = 0; shift < 32; shift += 8) bytes.push_back((v >> shift) & 0xFF);
    }
  };
  entry(256, 3, 16);
  entry(257, 3, 16);
  entry(273, 4, strip_offset);
  entry(279, 4, strip_bytes);
  bytes.resize(file_bytes, 0);
  return bytes;
}

TEST(CheckImageComplete, TiffStripsMustLieInsideTheFile) {
  EXPECT_TRUE(CheckImageComplete(HandMadeTiff(100, 256, 356)).ok());
  EXPECT_THAT(CheckImageComplete(HandMadeTiff(100, 256, 355)).message(),
              HasSubstr("truncated: the TIFF image data extends past the end of the file"));
  const Result<ImageHeader> header = ReadImageHeader(HandMadeTiff(100, 256, 356));
  ASSERT_TRUE(header.ok()) << header.status();
  EXPECT_EQ(header->width, 16);
}

TEST(CheckImageComplete, IgnoresDataAfterTheEnd) {
  const cv::Mat image = testing_util::TestPattern(200, 150);
  for (const char* extension : {".jpg", ".png"}) {
    SCOPED_TRACE(extension);
    std::vector<std::uint8_t> bytes = testing_util::Encode(image, extension);
    for (int i = 0; i < 1000; ++i) bytes.push_back(static_cast<std::uint8_t>(i * 37));
    EXPECT_TRUE(CheckImageComplete(bytes).ok()) << CheckImageComplete(bytes);
  }
}

TEST(CheckImageComplete, JpegEmbeddedThumbnailDoesNotEndTheImage) {
  // A JPEG thumbnail inside an APP1 segment contains its own EOI; the walk must skip it.
  const std::vector<std::uint8_t> full =
      testing_util::Encode(testing_util::TestPattern(200, 150), ".jpg");
  const std::vector<std::uint8_t> thumbnail =
      testing_util::Encode(testing_util::TestPattern(20, 15), ".jpg");
  std::vector<std::uint8_t> bytes = {0xFF, 0xD8, 0xFF, 0xE1};
  const std::size_t length = thumbnail.size() + 2;
  bytes.push_back(static_cast<std::uint8_t>(length >> 8));
  bytes.push_back(static_cast<std::uint8_t>(length & 0xFF));
  bytes.insert(bytes.end(), thumbnail.begin(), thumbnail.end());
  bytes.insert(bytes.end(), full.begin() + 2, full.end());
  EXPECT_TRUE(CheckImageComplete(bytes).ok());
  const Result<ImageHeader> header = ReadImageHeader(bytes);
  ASSERT_TRUE(header.ok());
  EXPECT_EQ(header->width, 200);
  // Truncating the main image is still noticed although the thumbnail's EOI is present.
  EXPECT_FALSE(CheckImageComplete(Prefix(bytes, bytes.size() - 100)).ok());
}

}  // namespace
}  // namespace reconduit
