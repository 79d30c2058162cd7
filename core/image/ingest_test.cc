#include "core/image/ingest.h"

#include "core/image/test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

const std::filesystem::path kKermitImages = "../shared/datasets/kermit/images";

TEST(IngestOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(IngestOptions().Check(&error)) << error;
  IngestOptions options;
  options.num_threads = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("num_threads = -1"));
  options = IngestOptions();
  options.reader.min_side = -3;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("min_side = -3"));
}

// A folder with good and bad files, named so that name order differs from creation order.
class IngestTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const cv::Mat pattern = testing_util::TestPattern(320, 240);
    const std::vector<std::uint8_t> jpeg = testing_util::Encode(pattern, ".jpg");
    testing_util::WriteBytes(dir_ / "d_good.jpg", jpeg);
    testing_util::WriteText(dir_ / "b_text.jpg", "not an image");
    testing_util::WriteBytes(dir_ / "c_cut.jpg", std::vector<std::uint8_t>(
                                                     jpeg.begin(), jpeg.begin() + jpeg.size() / 2));
    testing_util::WriteBytes(dir_ / "a_good.png", testing_util::Encode(pattern, ".png"));
    testing_util::WriteBytes(dir_ / "e_good.tif", testing_util::Encode(pattern, ".tif"));
    testing_util::WriteText(dir_ / ".hidden.jpg", "ignored");
    std::filesystem::create_directory(dir_ / "subfolder");
  }

  std::vector<std::filesystem::path> Files(const std::vector<std::string>& names) const {
    std::vector<std::filesystem::path> files;
    for (const std::string& name : names) files.push_back(dir_ / name);
    return files;
  }

  static std::vector<std::string> Names(const IngestReport& report) {
    std::vector<std::string> names;
    for (const ImageRecord& record : report.images) names.push_back(record.name);
    return names;
  }

  testing_util::ScopedTempDir dir_;
  IngestOptions options_;
  Progress progress_;
  CancelToken cancel_;
};

TEST_F(IngestTest, ListsRegularVisibleFilesByName) {
  const Result<std::vector<std::filesystem::path>> files = ListImageFiles(dir_.path());
  ASSERT_TRUE(files.ok()) << files.status();
  EXPECT_EQ(*files, Files({"a_good.png", "b_text.jpg", "c_cut.jpg", "d_good.jpg", "e_good.tif"}));
  EXPECT_EQ(ListImageFiles(dir_ / "nope").status().code(), StatusCode::kNotFound);
}

TEST_F(IngestTest, KeepsInputOrderAndRejectsOnlyBadFiles) {
  for (int num_threads : {1, 2, 4}) {
    SCOPED_TRACE(num_threads);
    options_.num_threads = num_threads;
    const IngestReport report = IngestImages(
        Files({"e_good.tif", "c_cut.jpg", "d_good.jpg", "b_text.jpg", "a_good.png", "missing.jpg"}),
        options_, progress_, cancel_);
    EXPECT_THAT(Names(report), ElementsAre("e_good.tif", "c_cut.jpg", "d_good.jpg", "b_text.jpg",
                                           "a_good.png", "missing.jpg"));
    ASSERT_EQ(report.images.size(), 6u);
    EXPECT_TRUE(report.images[0].accepted()) << report.images[0].status;
    EXPECT_THAT(report.images[1].status.message(), HasSubstr("c_cut.jpg: truncated"));
    EXPECT_TRUE(report.images[2].accepted()) << report.images[2].status;
    EXPECT_EQ(report.images[3].status.message(), "b_text.jpg: not a JPEG, PNG or TIFF image");
    EXPECT_TRUE(report.images[4].accepted()) << report.images[4].status;
    EXPECT_EQ(report.images[5].status.code(), StatusCode::kNotFound);
    EXPECT_EQ(report.num_accepted, 3u);
    EXPECT_EQ(report.num_rejected, 3u);
    EXPECT_EQ(report.images[0].info.format, ImageFormat::kTiff);
    EXPECT_EQ(report.images[4].info.format, ImageFormat::kPng);
    EXPECT_EQ(report.images[2].info.width, 320);
    EXPECT_GT(report.images[2].info.file_bytes, 0);
    EXPECT_EQ(progress_.done(), 6u);
    EXPECT_EQ(progress_.total(), 6u);
  }
}

TEST_F(IngestTest, IngestDirectoryUsesNameOrder) {
  const Result<IngestReport> report = IngestDirectory(dir_.path(), options_, progress_, cancel_);
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_THAT(Names(*report),
              ElementsAre("a_good.png", "b_text.jpg", "c_cut.jpg", "d_good.jpg", "e_good.tif"));
  EXPECT_EQ(report->num_accepted, 3u);
  EXPECT_EQ(IngestDirectory(dir_ / "nope", options_, progress_, cancel_).status().code(),
            StatusCode::kNotFound);
}

TEST_F(IngestTest, EmptyInputGivesEmptyReport) {
  const IngestReport report = IngestImages({}, options_, progress_, cancel_);
  EXPECT_TRUE(report.images.empty());
  EXPECT_EQ(report.num_accepted, 0u);
  EXPECT_EQ(report.num_rejected, 0u);
}

TEST_F(IngestTest, CanceledBeforeStartThrows) {
  cancel_.RequestCancel();
  EXPECT_THROW(IngestImages(Files({"a_good.png", "d_good.jpg"}), options_, progress_, cancel_),
               CanceledError);
  EXPECT_EQ(progress_.done(), 0u);
}

TEST_F(IngestTest, CancellationStopsRemainingFiles) {
  // Cancel from the progress callback once two files are done; one thread makes the count
  // deterministic.
  const CancelToken cancel;
  std::atomic<int> calls{0};
  Progress progress(
      [&](const ProgressUpdate& update) {
        ++calls;
        if (update.done >= 2) cancel.RequestCancel();
      },
      std::chrono::milliseconds(0));
  options_.num_threads = 1;
  std::vector<std::filesystem::path> files;
  for (int i = 0; i < 20; ++i) files.push_back(dir_ / "d_good.jpg");
  EXPECT_THROW(IngestImages(files, options_, progress, cancel), CanceledError);
  EXPECT_EQ(progress.done(), 2u);
  EXPECT_GT(calls.load(), 0);
}

TEST_F(IngestTest, InvalidOptionsThrow) {
  options_.reader.min_side = 0;
  EXPECT_THROW(IngestImages(Files({"a_good.png"}), options_, progress_, cancel_), CheckError);
}

TEST(Ingest, KermitDatasetIsAcceptedWithFocalPriors) {
  if (!std::filesystem::is_directory(kKermitImages)) {
    GTEST_SKIP() << "dataset missing: " << kKermitImages << " (run from the repository root)";
  }
  Progress progress;
  IngestOptions options;
  options.reader.max_side = 320;
  const Result<IngestReport> report =
      IngestDirectory(kKermitImages, options, progress, CancelToken());
  ASSERT_TRUE(report.ok()) << report.status();
  ASSERT_EQ(report->images.size(), 11u);
  EXPECT_EQ(report->num_accepted, 11u);
  for (const ImageRecord& record : report->images) {
    SCOPED_TRACE(record.name);
    EXPECT_EQ(record.info.format, ImageFormat::kJpeg);
    EXPECT_EQ(record.info.width, 640);
    EXPECT_EQ(record.info.height, 480);
    EXPECT_EQ(record.info.working_width, 320);
    ASSERT_TRUE(record.info.focal.has_value());
    EXPECT_NEAR(record.info.focal->focal_px, 661.0, 5.0);
    ASSERT_TRUE(record.info.exif.has_value());
    EXPECT_EQ(record.info.exif->camera_model, "Canon PowerShot A10");
  }
}

}  // namespace
}  // namespace reconduit
