#include "core/image/image_reader.h"

#include "core/image/exif_test_util.h"
#include "core/image/test_util.h"
#include "core/util/timer.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

using testing_util::WriteJpegWithExif;

class ImageReaderTest : public ::testing::Test {
 protected:
  // Inspects `name` in the temp directory with default options.
  ImageRecord Inspect(const std::string& name) const { return InspectImage(dir_ / name, options_); }

  testing_util::ScopedTempDir dir_;
  ImageReaderOptions options_;
  const cv::Mat pattern_ = testing_util::TestPattern(320, 240);
};

TEST(ImageReaderOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(ImageReaderOptions().Check(&error)) << error;
}

TEST(ImageReaderOptions, RejectsOutOfRangeValues) {
  std::string error;
  ImageReaderOptions options;
  options.min_side = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("min_side = 0"));
  options = ImageReaderOptions();
  options.max_pixels = 100;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("max_pixels"));
  options = ImageReaderOptions();
  options.max_side = -1;
  EXPECT_FALSE(options.Check(nullptr));
  options = ImageReaderOptions();
  options.max_file_bytes = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("max_file_bytes"));
  // Consumers re-assert validity.
  options.max_file_bytes = -5;
  EXPECT_THROW(InspectImage("whatever.jpg", options), CheckError);
}

TEST_F(ImageReaderTest, AcceptsJpegPngAndTiff) {
  for (const char* extension : {".jpg", ".png", ".tif"}) {
    SCOPED_TRACE(extension);
    const std::string name = std::string("photo") + extension;
    const std::vector<std::uint8_t> bytes = testing_util::Encode(pattern_, extension);
    testing_util::WriteBytes(dir_ / name, bytes);
    const ImageRecord record = Inspect(name);
    ASSERT_TRUE(record.accepted()) << record.status;
    EXPECT_EQ(record.name, name);
    EXPECT_EQ(record.info.width, 320);
    EXPECT_EQ(record.info.height, 240);
    EXPECT_EQ(record.info.file_bytes, static_cast<std::int64_t>(bytes.size()));
    EXPECT_EQ(record.info.orientation, 1);
    EXPECT_FALSE(record.info.focal.has_value());
  }
  EXPECT_EQ(Inspect("photo.tif").info.format, ImageFormat::kTiff);
}

TEST_F(ImageReaderTest, TiffRoundTripKeepsPixels) {
  testing_util::WriteBytes(dir_ / "lossless.tif", testing_util::Encode(pattern_, ".tif"));
  const Result<cv::Mat> image = ReadImage(dir_ / "lossless.tif", options_);
  ASSERT_TRUE(image.ok()) << image.status();
  ASSERT_EQ(image->type(), CV_8UC3);
  EXPECT_EQ(cv::norm(*image, pattern_, cv::NORM_INF), 0.0);
}

TEST_F(ImageReaderTest, DetectsFormatByContentNotName) {
  testing_util::WriteBytes(dir_ / "really_a_png.jpg", testing_util::Encode(pattern_, ".png"));
  const ImageRecord record = Inspect("really_a_png.jpg");
  ASSERT_TRUE(record.accepted()) << record.status;
  EXPECT_EQ(record.info.format, ImageFormat::kPng);
}

TEST_F(ImageReaderTest, RejectsNonImage) {
  testing_util::WriteText(dir_ / "notes.jpg", "These are not the pixels you are looking for.\n");
  const ImageRecord record = Inspect("notes.jpg");
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(record.status.message(), "notes.jpg: not a JPEG, PNG or TIFF image");
  EXPECT_EQ(record.info.format, ImageFormat::kUnknown);
}

TEST_F(ImageReaderTest, RejectsEmptyAndMissingFiles) {
  testing_util::WriteText(dir_ / "empty.jpg", "");
  EXPECT_EQ(Inspect("empty.jpg").status.message(), "empty.jpg: the file is empty");
  const ImageRecord missing = Inspect("missing.jpg");
  EXPECT_EQ(missing.status.code(), StatusCode::kNotFound);
  EXPECT_THAT(missing.status.message(), HasSubstr("missing.jpg"));
}

TEST_F(ImageReaderTest, RejectsTruncatedJpeg) {
  const std::vector<std::uint8_t> jpeg = testing_util::Encode(pattern_, ".jpg");
  testing_util::WriteBytes(dir_ / "half.jpg",
                           std::vector<std::uint8_t>(jpeg.begin(), jpeg.begin() + jpeg.size() / 2));
  const ImageRecord record = Inspect("half.jpg");
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(record.status.message(),
            "half.jpg: truncated: the JPEG data ends before its end-of-image marker");
  EXPECT_FALSE(ReadImage(dir_ / "half.jpg", options_).ok());
}

TEST_F(ImageReaderTest, RejectsTruncatedPng) {
  const std::vector<std::uint8_t> png = testing_util::Encode(pattern_, ".png");
  testing_util::WriteBytes(dir_ / "half.png",
                           std::vector<std::uint8_t>(png.begin(), png.begin() + png.size() / 2));
  const ImageRecord record = Inspect("half.png");
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(record.status.message(), HasSubstr("half.png: truncated"));
}

TEST_F(ImageReaderTest, AcceptsJpegWithJunkAfterEndMarker) {
  std::vector<std::uint8_t> jpeg = testing_util::Encode(pattern_, ".jpg");
  for (int i = 0; i < 4096; ++i) jpeg.push_back(static_cast<std::uint8_t>(i * 131 + 7));
  testing_util::WriteBytes(dir_ / "junk.jpg", jpeg);
  const ImageRecord record = Inspect("junk.jpg");
  ASSERT_TRUE(record.accepted()) << record.status;
  EXPECT_EQ(record.info.width, 320);
}

TEST_F(ImageReaderTest, RejectsCorruptData) {
  std::vector<std::uint8_t> png = testing_util::Encode(pattern_, ".png");
  // Scramble the compressed data inside the first IDAT chunk, keeping the chunk structure, so
  // the file is complete but its pixels do not decode.
  const std::string idat = "IDAT";
  const auto it = std::search(png.begin(), png.end(), idat.begin(), idat.end());
  ASSERT_NE(it, png.end());
  const auto data_start = static_cast<std::size_t>(it - png.begin()) + 4;
  std::size_t data_length = 0;
  for (auto byte = it - 4; byte != it; ++byte) data_length = (data_length << 8) | *byte;
  ASSERT_GT(data_length, 100u);
  for (std::size_t i = 2; i < data_length; ++i) {
    png[data_start + i] = static_cast<std::uint8_t>(i * 13 + 5);
  }
  testing_util::WriteBytes(dir_ / "corrupt.png", png);
  const ImageRecord record = Inspect("corrupt.png");
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(record.status.message(), HasSubstr("corrupt.png: the PNG data could not be decoded"));
}

TEST_F(ImageReaderTest, RejectsTinyImage) {
  testing_util::WriteBytes(dir_ / "dot.png",
                           testing_util::Encode(testing_util::TestPattern(1, 1), ".png"));
  const ImageRecord record = Inspect("dot.png");
  EXPECT_EQ(record.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(record.status.message(),
            "dot.png: image is 1x1 pixels; the minimum is 100 pixels per side");
  options_.min_side = 1;
  EXPECT_TRUE(Inspect("dot.png").accepted());
}

TEST_F(ImageReaderTest, RefusesDecompressionBombFromHeader) {
  testing_util::WriteBytes(dir_ / "bomb.png", testing_util::PngHeaderOnly(100000, 100000));
  const ImageRecord record = Inspect("bomb.png");
  // The reason is the size, not the missing pixel data: the limit is checked before anything
  // is decoded.
  EXPECT_EQ(record.status.code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(record.status.message(),
            "bomb.png: image is 100000x100000 pixels (10000.0 megapixels); the maximum is "
            "100.0 megapixels");
  EXPECT_EQ(record.info.format, ImageFormat::kPng);
}

TEST_F(ImageReaderTest, RefusesFilesOverTheByteLimit) {
  testing_util::WriteBytes(dir_ / "big.png", testing_util::Encode(pattern_, ".png"));
  options_.max_file_bytes = 1000;
  const ImageRecord record = Inspect("big.png");
  EXPECT_EQ(record.status.code(), StatusCode::kResourceExhausted);
  EXPECT_THAT(record.status.message(), HasSubstr("the maximum is 1000 bytes"));
}

TEST_F(ImageReaderTest, AppliesExifOrientation) {
  WriteJpegWithExif(dir_ / "rotated.jpg", testing_util::Encode(pattern_, ".jpg"), 6);
  const ImageRecord record = Inspect("rotated.jpg");
  ASSERT_TRUE(record.accepted()) << record.status;
  EXPECT_EQ(record.info.orientation, 6);
  EXPECT_EQ(record.info.width, 240);
  EXPECT_EQ(record.info.height, 320);
  ASSERT_TRUE(record.info.exif.has_value());
  EXPECT_EQ(record.info.exif->camera_make, "Reconduit");
  // The focal prior refers to the oriented image (long side 320).
  ASSERT_TRUE(record.info.focal.has_value());
  EXPECT_DOUBLE_EQ(record.info.focal->focal_px, 24.0 / 36.0 * 320.0);

  const Result<cv::Mat> image = ReadImage(dir_ / "rotated.jpg", options_);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->cols, 240);
  EXPECT_EQ(image->rows, 320);
  // The displayed top-left pixel is the stored bottom-left one (lossy JPEG: compare loosely).
  const cv::Vec3b expected = pattern_.at<cv::Vec3b>(239, 0);
  const cv::Vec3b actual = image->at<cv::Vec3b>(0, 0);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(actual[c], expected[c], 40) << "channel " << c;

  // read_exif = false: no EXIF fields or focal prior, but the orientation still applies.
  options_.read_exif = false;
  const ImageRecord without_exif = Inspect("rotated.jpg");
  ASSERT_TRUE(without_exif.accepted());
  EXPECT_FALSE(without_exif.info.exif.has_value());
  EXPECT_FALSE(without_exif.info.focal.has_value());
  EXPECT_EQ(without_exif.info.width, 240);
}

TEST_F(ImageReaderTest, ReadImageDownscalesToWorkingSize) {
  testing_util::WriteBytes(dir_ / "photo.png", testing_util::Encode(pattern_, ".png"));
  options_.max_side = 160;
  const ImageRecord record = Inspect("photo.png");
  ASSERT_TRUE(record.accepted());
  EXPECT_EQ(record.info.width, 320);
  EXPECT_EQ(record.info.working_width, 160);
  EXPECT_EQ(record.info.working_height, 120);
  const Result<cv::Mat> image = ReadImage(dir_ / "photo.png", options_);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->size(), cv::Size(160, 120));
  EXPECT_EQ(image->type(), CV_8UC3);
  // Grey images come back as 3-channel BGR.
  cv::Mat grey;
  cv::extractChannel(pattern_, grey, 0);
  testing_util::WriteBytes(dir_ / "grey.png", testing_util::Encode(grey, ".png"));
  options_.max_side = 0;
  const Result<cv::Mat> grey_image = ReadImage(dir_ / "grey.png", options_);
  ASSERT_TRUE(grey_image.ok());
  EXPECT_EQ(grey_image->type(), CV_8UC3);
  EXPECT_EQ(grey_image->size(), cv::Size(320, 240));
}

// A smooth picture (small as a JPEG) of the given size.
cv::Mat SmoothPicture(int width, int height) {
  cv::Mat small = testing_util::TestPattern(64, 48);
  cv::Mat picture;
  cv::resize(small, picture, cv::Size(width, height), 0, 0, cv::INTER_LINEAR);
  return picture;
}

// A JPEG much larger than its working size is decoded at reduced scale, then resized: the
// result has the working size and the pixels of a full decode plus resize, also when EXIF
// rotates it.
TEST_F(ImageReaderTest, LargeJpegDecodedAtReducedScaleMatchesFullDecode) {
  const cv::Mat picture = SmoothPicture(2000, 1200);
  testing_util::WriteBytes(dir_ / "big.jpg", testing_util::Encode(picture, ".jpg"));
  WriteJpegWithExif(dir_ / "turned.jpg", testing_util::Encode(picture, ".jpg"), 6);
  options_.max_side = 450;  // 1/4 scale (500 x 300) still covers 450 x 270.
  ImageInfo info;
  const Result<cv::Mat> image = ReadImage(dir_ / "big.jpg", options_, &info);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->size(), cv::Size(450, 270));
  EXPECT_EQ(info.width, 2000);
  EXPECT_EQ(info.height, 1200);
  cv::Mat full = cv::imread((dir_ / "big.jpg").string(), cv::IMREAD_COLOR);
  cv::Mat expected;
  cv::resize(full, expected, cv::Size(450, 270), 0, 0, cv::INTER_AREA);
  cv::Mat difference;
  cv::absdiff(*image, expected, difference);
  EXPECT_LT(cv::mean(difference)[0], 2.0);

  const Result<cv::Mat> turned = ReadImage(dir_ / "turned.jpg", options_, &info);
  ASSERT_TRUE(turned.ok()) << turned.status();
  EXPECT_EQ(turned->size(), cv::Size(270, 450));
  EXPECT_EQ(info.width, 1200);
  // Sizes that are not multiples of the factor round up as libjpeg does.
  const cv::Mat odd = SmoothPicture(1001, 803);
  testing_util::WriteBytes(dir_ / "odd.jpg", testing_util::Encode(odd, ".jpg"));
  options_.max_side = 250;  // 1/4: 251 x 201.
  const Result<cv::Mat> odd_image = ReadImage(dir_ / "odd.jpg", options_);
  ASSERT_TRUE(odd_image.ok()) << odd_image.status();
  EXPECT_EQ(odd_image->size(), WorkingSize(1001, 803, 250));
}

// Issue 12: reading a 48 Mpx JPEG at 1000 px must not hold its full-size pixels (144 MB).
TEST_F(ImageReaderTest, LargeJpegAtWorkingSizeNeverHoldsTheFullPixels) {
  {
    const cv::Mat picture = SmoothPicture(8000, 6000);
    testing_util::WriteBytes(dir_ / "huge.jpg", testing_util::Encode(picture, ".jpg"));
  }
  options_.max_side = 1000;
  const std::int64_t before = CurrentMemoryBytes();
  const StagePeakMemory peak;
  if (!peak.Own()) GTEST_SKIP() << "no per-stretch peak memory here (/proc/self/clear_refs)";
  const Result<cv::Mat> image = ReadImage(dir_ / "huge.jpg", options_);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->size(), cv::Size(1000, 750));
  const std::int64_t grown = peak.PeakBytes() - before;
  EXPECT_LT(grown, 60 << 20) << "peak grew by " << (grown >> 20) << " MiB";
}

TEST(ApplyExifOrientation, AllEightOrientations) {
  // Stored 3 x 2 image with distinct corners; per the EXIF spec, which stored corner appears
  // at the displayed top-left, and the displayed size.
  cv::Mat stored = (cv::Mat_<std::uint8_t>(2, 3) << 1, 2, 3, 4, 5, 6);
  const std::uint8_t top_left = 1, top_right = 3, bottom_left = 4, bottom_right = 6;
  struct Case {
    int orientation;
    std::uint8_t displayed_top_left;
    cv::Size size;
  };
  const Case cases[] = {{1, top_left, {3, 2}},     {2, top_right, {3, 2}},
                        {3, bottom_right, {3, 2}}, {4, bottom_left, {3, 2}},
                        {5, top_left, {2, 3}},     {6, bottom_left, {2, 3}},
                        {7, bottom_right, {2, 3}}, {8, top_right, {2, 3}},
                        {0, top_left, {3, 2}},     {9, top_left, {3, 2}}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.orientation);
    const cv::Mat displayed = ApplyExifOrientation(stored, c.orientation);
    EXPECT_EQ(displayed.size(), c.size);
    EXPECT_EQ(displayed.at<std::uint8_t>(0, 0), c.displayed_top_left);
  }
  // Orientation 6 completely: rows of the displayed image are stored columns, bottom to top.
  const cv::Mat rotated = ApplyExifOrientation(stored, 6);
  const cv::Mat expected = (cv::Mat_<std::uint8_t>(3, 2) << 4, 1, 5, 2, 6, 3);
  EXPECT_EQ(cv::norm(rotated, expected, cv::NORM_INF), 0.0);
}

TEST(WorkingSize, KeepsAspectAndNeverUpscales) {
  EXPECT_EQ(WorkingSize(3072, 2048, 0), cv::Size(3072, 2048));
  EXPECT_EQ(WorkingSize(3072, 2048, 4000), cv::Size(3072, 2048));
  EXPECT_EQ(WorkingSize(3072, 2048, 1536), cv::Size(1536, 1024));
  EXPECT_EQ(WorkingSize(2048, 3072, 1536), cv::Size(1024, 1536));
  EXPECT_EQ(WorkingSize(1000, 1, 100), cv::Size(100, 1));
}

}  // namespace
}  // namespace reconduit
