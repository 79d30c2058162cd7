#include "core/feature/features.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

TEST(FeatureFile, RoundTripAndTruncation) {
  FeatureSet features;
  features.image_width = 640;
  features.image_height = 480;
  for (int i = 0; i < 5; ++i) {
    features.keypoints.push_back({1.5f * i, 2.0f * i, 3.0f, 0.5f, 0.01f * i});
  }
  features.descriptors = cv::Mat(5, 128, CV_8U);
  cv::RNG(3).fill(features.descriptors, cv::RNG::UNIFORM, 0, 256);

  const fs::path path =
      fs::temp_directory_path() / ("reconduit_features_test_" + std::to_string(getpid()) + ".feat");
  ASSERT_TRUE(WriteFeatures(path, features).ok());
  auto read = ReadFeatures(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->image_width, 640);
  ASSERT_EQ(read->size(), 5u);
  EXPECT_FLOAT_EQ(read->keypoints[4].x, 6.0f);
  EXPECT_EQ(cv::norm(read->descriptors, features.descriptors, cv::NORM_L1), 0.0);

  fs::resize_file(path, fs::file_size(path) - 10);
  auto truncated = ReadFeatures(path);
  EXPECT_FALSE(truncated.ok());
  EXPECT_NE(truncated.status().message().find("does not match"), std::string::npos);
  std::ofstream(path) << "hello";
  EXPECT_FALSE(ReadFeatures(path).ok());
  fs::remove(path);
  EXPECT_EQ(ReadFeatures(path).status().code(), StatusCode::kNotFound);
}

TEST(FeatureFile, EmptySetRoundTrips) {
  FeatureSet features;
  features.image_width = 10;
  features.image_height = 10;
  features.descriptors = cv::Mat(0, 128, CV_8U);
  const fs::path path = fs::temp_directory_path() /
                        ("reconduit_features_empty_" + std::to_string(getpid()) + ".feat");
  ASSERT_TRUE(WriteFeatures(path, features).ok());
  auto read = ReadFeatures(path);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->size(), 0u);
  fs::remove(path);
}

}  // namespace
}  // namespace reconduit
