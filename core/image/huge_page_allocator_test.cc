#include "core/image/huge_page_allocator.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cstdint>

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

TEST(HugePageAllocatorTest, OpenCvResultsDoNotDependOnTheAllocator) {
  cv::Mat input(1500, 1200, CV_32F);
  cv::randu(input, 0.0, 255.0);
  cv::Mat expected;
  cv::GaussianBlur(input, expected, cv::Size(), 1.6);
  cv::Mat ours;
  {
    ScopedHugePageMatAllocator scope;
    cv::GaussianBlur(input, ours, cv::Size(), 1.6);
    cv::Mat doubled;
    cv::resize(input, doubled, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
    EXPECT_EQ(doubled.u->currAllocator, HugePageMatAllocator());
  }
  ASSERT_EQ(ours.u->currAllocator, HugePageMatAllocator());
  EXPECT_EQ(cv::norm(ours, expected, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace reconduit
