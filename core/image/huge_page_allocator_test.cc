#include "core/image/huge_page_allocator.h"

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace reconduit {
namespace {

TEST(HugePageAllocatorTest, InstallsAndRestoresTheDefault) {
  cv::MatAllocator* before = cv::Mat::getDefaultAllocator();
  {
    ScopedHugePageMatAllocator scope;
    EXPECT_EQ(cv::Mat::getDefaultAllocator(), HugePageMatAllocator());
  }
  EXPECT_EQ(cv::Mat::getDefaultAllocator(), before);
}

TEST(HugePageAllocatorTest, LargeBuffersAreAlignedAndOutliveTheScope) {
  cv::Mat large;
  cv::Mat small;
  {
    ScopedHugePageMatAllocator scope;
    large.create(2048, 1536, CV_32F);  // 12 MiB.
    small.create(16, 16, CV_8UC3);
  }
  ASSERT_EQ(large.u->currAllocator, HugePageMatAllocator());
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(large.data) % (std::uintptr_t{2} << 20), 0u);
  EXPECT_TRUE(large.isContinuous());
  EXPECT_EQ(large.step[0], 1536 * sizeof(float));
  EXPECT_EQ(large.step[1], sizeof(float));
  EXPECT_EQ(small.u->currAllocator, cv::Mat::getStdAllocator());

  large.setTo(cv::Scalar(3.0));
  large.at<float>(2047, 1535) = 7.0f;
  EXPECT_EQ(large.at<float>(0, 0), 3.0f);
  EXPECT_EQ(large.at<float>(2047, 1535), 7.0f);
  cv::Mat copy = large.clone();  // Allocated by the standard allocator again.
  EXPECT_EQ(copy.u->currAllocator, cv::Mat::getStdAllocator());
  EXPECT_EQ(cv::norm(copy, large, cv::NORM_INF), 0.0);
}

TEST(HugePageAllocatorTest, MultiDimensionalStepsMatchTheStandardLayout) {
  const int sizes[] = {8, 512, 400};
  cv::Mat expected(3, sizes, CV_16SC2);
  cv::Mat ours;
  {
    ScopedHugePageMatAllocator scope;
    ours.create(3, sizes, CV_16SC2);  // 6.25 MiB.
  }
  ASSERT_EQ(ours.u->currAllocator, HugePageMatAllocator());
  for (int i = 0; i < 3; ++i) EXPECT_EQ(ours.step[i], expected.step[i]) << i;
}

// SIFT, the allocator's customer, finds the same keypoints and descriptors with it.
TEST(HugePageAllocatorTest, SiftResultsDoNotDependOnTheAllocator) {
  cv::Mat image(900, 1200, CV_8U);
  cv::randu(image, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(), 2.0);  // Blobs at many scales.
  std::vector<cv::KeyPoint> expected_keypoints, keypoints;
  cv::Mat expected_descriptors, descriptors;
  cv::SIFT::create()->detectAndCompute(image, cv::noArray(), expected_keypoints,
                                       expected_descriptors);
  {
    ScopedHugePageMatAllocator scope;
    cv::SIFT::create()->detectAndCompute(image, cv::noArray(), keypoints, descriptors);
  }
  ASSERT_GT(expected_keypoints.size(), 100u);
  ASSERT_EQ(keypoints.size(), expected_keypoints.size());
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    ASSERT_EQ(keypoints[i].pt, expected_keypoints[i].pt) << i;
  }
  EXPECT_EQ(cv::norm(descriptors, expected_descriptors, cv::NORM_INF), 0.0);
}

// The advice reaches the kernel: the mapping of a large buffer carries the "hg" (huge pages
// advised) flag in /proc/self/smaps.
TEST(HugePageAllocatorTest, KernelSeesTheHugePageAdvice) {
  if (!std::filesystem::exists("/sys/kernel/mm/transparent_hugepage")) {
    GTEST_SKIP() << "this kernel has no transparent huge pages";
  }
  cv::Mat large;
  {
    ScopedHugePageMatAllocator scope;
    large.create(4096, 1024, CV_32F);  // 16 MiB.
  }
  const auto address = reinterpret_cast<std::uintptr_t>(large.data);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  bool found = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t begin = 0, end = 0;
    char dash = 0;
    std::istringstream range(line);
    if (range >> std::hex >> begin >> dash >> end && dash == '-') {
      inside = begin <= address && address < end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      found = true;
      EXPECT_NE((line + " ").find(" hg "), std::string::npos) << line;
    }
  }
  EXPECT_TRUE(found) << "no mapping holds the buffer";
}

}  // namespace
}  // namespace reconduit
