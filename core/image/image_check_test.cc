#include "core/image/image_check.h"

#include "core/image/exif_test_util.h"
#include "core/image/image_reader.h"
#include "core/image/test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

using testing_util::WriteJpegWithExif;

// PNG bytes whose first IDAT chunk's compressed data is scrambled, chunk structure kept: the
// header and the IEND marker are intact but the pixels do not decode.
std::vector<std::uint8_t> PngCorruptInTheMiddle(const cv::Mat& image) {
  std::vector<std::uint8_t> png = testing_util::Encode(image, ".png");
  const std::string idat = "IDAT";
  const auto it = std::search(png.begin(), png.end(), idat.begin(), idat.end());
  const auto data_start = static_cast<std::size_t>(it - png.begin()) + 4;
  std::size_t data_length = 0;
  for (auto byte = it - 4; byte != it; ++byte) data_length = (data_length << 8) | *byte;
  for (std::size_t i = 2; i < data_length; ++i) {
    png[data_start + i] = static_cast<std::uint8_t>(i * 13 + 5);
  }
  return png;
}

class ImageCheckTest : public ::testing::Test {
 protected:
  ImageRecord Check(const std::string& name) const {
    return InspectImageHeader(dir_ / name, options_);
  }

  testing_util::ScopedTempDir dir_;
  ImageReaderOptions options_;
  const cv::Mat pattern_ = testing_util::TestPattern(320, 240);
};

TEST_F(ImageCheckTest, DescribesAPhotoFromItsHeaderAndExif) {
  WriteJpegWithExif(dir_ / "rotated.jpg", testing_util::Encode(pattern_, ".jpg"), 6);
  options_.max_side = 160;
  std::vector<std::uint8_t> bytes;
  const ImageRecord record = InspectImageHeader(dir_ / "rotated.jpg", options_, &bytes);
  ASSERT_TRUE(record.accepted()) << record.status;
  EXPECT_EQ(record.name, "rotated.jpg");
  EXPECT_EQ(record.info.format, ImageFormat::kJpeg);
  EXPECT_EQ(record.info.file_bytes, static_cast<std::int64_t>(bytes.size()));
  // Orientation 6 turns the stored 320 x 240 into 240 x 320 as displayed.
  EXPECT_EQ(record.info.orientation, 6);
  EXPECT_EQ(record.info.width, 240);
  EXPECT_EQ(record.info.height, 320);
  EXPECT_EQ(record.info.working_width, 120);
  EXPECT_EQ(record.info.working_height, 160);
  ASSERT_TRUE(record.info.exif.has_value());
  EXPECT_EQ(record.info.exif->camera_make, "Reconduit");
  EXPECT_EQ(record.info.exif->camera_model, "Test 1");
  ASSERT_TRUE(record.info.focal.has_value());
  EXPECT_DOUBLE_EQ(record.info.focal->focal_px, 24.0 / 36.0 * 320.0);
  EXPECT_EQ(record.ReasonWithoutName(), "");

  // The facts later readers keep.
  const PhotoMetadata photo = record.Metadata();
  EXPECT_EQ(photo.bytes, record.info.file_bytes);
  EXPECT_EQ(photo.width, 240);
  EXPECT_EQ(photo.height, 320);
  EXPECT_EQ(photo.exif_focal_px, record.info.focal->focal_px);
  EXPECT_EQ(photo.focal_source, FocalSourceName(record.info.focal->source));
  EXPECT_EQ(photo.make, "Reconduit");
  EXPECT_EQ(photo.model, "Test 1");
  EXPECT_TRUE(photo.accepted);
  EXPECT_EQ(photo.reason, "");

  // The full inspection, which decodes, agrees on everything.
  const ImageRecord decoded = InspectImage(dir_ / "rotated.jpg", options_);
  ASSERT_TRUE(decoded.accepted()) << decoded.status;
  EXPECT_EQ(decoded.info.width, record.info.width);
  EXPECT_EQ(decoded.info.height, record.info.height);
  EXPECT_EQ(decoded.info.working_width, record.info.working_width);
  EXPECT_EQ(decoded.info.working_height, record.info.working_height);
  EXPECT_EQ(decoded.info.focal->focal_px, record.info.focal->focal_px);
}

TEST_F(ImageCheckTest, RefusesTruncatedFiles) {
  const std::vector<std::uint8_t> jpeg = testing_util::Encode(pattern_, ".jpg");
  testing_util::WriteBytes(dir_ / "half.jpg",
                           std::vector<std::uint8_t>(jpeg.begin(), jpeg.begin() + jpeg.size() / 2));
  std::vector<std::uint8_t> bytes = {1, 2, 3};
  const ImageRecord record = InspectImageHeader(dir_ / "half.jpg", options_, &bytes);
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(record.status.message(),
            "half.jpg: truncated: the JPEG data ends before its end-of-image marker");
  EXPECT_EQ(record.ReasonWithoutName(),
            "truncated: the JPEG data ends before its end-of-image marker");
  const PhotoMetadata photo = record.Metadata();
  EXPECT_FALSE(photo.accepted);
  EXPECT_EQ(photo.reason, "truncated: the JPEG data ends before its end-of-image marker");
  EXPECT_GT(photo.bytes, 0);
  EXPECT_FALSE(photo.exif_focal_px.has_value());
  // The bytes are handed over only for accepted photos.
  EXPECT_EQ(bytes, (std::vector<std::uint8_t>{1, 2, 3}));
}

TEST_F(ImageCheckTest, RefusesNonImagesBombsAndTinyImages) {
  testing_util::WriteText(dir_ / "notes.jpg", "not a photo at all");
  EXPECT_EQ(Check("notes.jpg").ReasonWithoutName(), "not a JPEG, PNG or TIFF image");
  testing_util::WriteBytes(dir_ / "bomb.png", testing_util::PngHeaderOnly(100000, 100000));
  EXPECT_EQ(Check("bomb.png").status.code(), StatusCode::kResourceExhausted);
  testing_util::WriteBytes(dir_ / "dot.png",
                           testing_util::Encode(testing_util::TestPattern(1, 1), ".png"));
  EXPECT_EQ(Check("dot.png").ReasonWithoutName(),
            "image is 1x1 pixels; the minimum is 100 pixels per side");
}

TEST_F(ImageCheckTest, CorruptionInsideCompressedDataIsLeftToTheDecoder) {
  testing_util::WriteBytes(dir_ / "corrupt.png", PngCorruptInTheMiddle(pattern_));
  // Header and end marker are intact: the header check, which never decodes, accepts it...
  const ImageRecord header = Check("corrupt.png");
  ASSERT_TRUE(header.accepted()) << header.status;
  EXPECT_EQ(header.info.width, 320);
  // ...and ingest's inspection, which decodes, refuses it with a reason.
  const ImageRecord decoded = InspectImage(dir_ / "corrupt.png", options_);
  EXPECT_FALSE(decoded.accepted());
  EXPECT_EQ(decoded.ReasonWithoutName().rfind("the PNG data could not be decoded", 0), 0u)
      << decoded.status;
  EXPECT_EQ(decoded.info.width, 0);
  EXPECT_EQ(decoded.info.format, ImageFormat::kPng);
}

TEST(WorkingSideLengths, KeepsAspectAndNeverUpscales) {
  EXPECT_EQ(WorkingSideLengths(4000, 3000, 0), std::make_pair(4000, 3000));
  EXPECT_EQ(WorkingSideLengths(4000, 3000, 5000), std::make_pair(4000, 3000));
  EXPECT_EQ(WorkingSideLengths(4000, 3000, 2000), std::make_pair(2000, 1500));
  EXPECT_EQ(WorkingSideLengths(3000, 4000, 2000), std::make_pair(1500, 2000));
  EXPECT_EQ(WorkingSideLengths(10000, 1, 100), std::make_pair(100, 1));
}

}  // namespace
}  // namespace reconduit
