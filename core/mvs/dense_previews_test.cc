#include "core/mvs/dense_previews.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

TEST(DensePreviewsTest, DepthPreviewIsSmallNearIsRedFarIsBlueEmptyIsBlack) {
  cv::Mat depth(400, 800, CV_32FC1, cv::Scalar(0));
  depth(cv::Rect(0, 0, 400, 400)).setTo(2.0f);    // Left half near.
  depth(cv::Rect(400, 0, 300, 400)).setTo(9.0f);  // Then far, then empty.
  const cv::Mat preview = RenderDepthPreview(depth, 200);
  ASSERT_EQ(preview.type(), CV_8UC3);
  EXPECT_EQ(preview.cols, 200);
  EXPECT_EQ(preview.rows, 100);
  const cv::Vec3b near = preview.at<cv::Vec3b>(50, 20), far = preview.at<cv::Vec3b>(50, 150),
                  empty = preview.at<cv::Vec3b>(50, 190);
  EXPECT_GT(near[2], near[0]) << "near is red";
  EXPECT_GT(far[0], far[2]) << "far is blue";
  EXPECT_EQ(empty, cv::Vec3b(0, 0, 0));
}

TEST(DensePreviewsTest, EmptyDepthMapGivesABlackPicture) {
  const cv::Mat preview = RenderDepthPreview(cv::Mat(30, 40, CV_32FC1, cv::Scalar(0)), 100);
  EXPECT_EQ(preview.size(), cv::Size(40, 30));
  EXPECT_EQ(cv::countNonZero(preview.reshape(1)), 0);
}

TEST(DensePreviewsTest, QualityGoesFromRedToGreenWithAgreeingViews) {
  cv::Mat quality(10, 50, CV_8UC1, cv::Scalar(0));
  for (int q = 1; q <= 4; ++q) quality(cv::Rect(10 * q, 0, 10, 10)).setTo(q);
  const cv::Mat preview = RenderQualityPreview(quality, 4, 0);
  EXPECT_EQ(preview.at<cv::Vec3b>(5, 5), cv::Vec3b(0, 0, 0));
  const cv::Vec3b one = preview.at<cv::Vec3b>(5, 15), two = preview.at<cv::Vec3b>(5, 25),
                  four = preview.at<cv::Vec3b>(5, 45);
  EXPECT_EQ(one[1], 0) << "only the photo itself: red";
  EXPECT_GT(two[2], two[0]);
  EXPECT_GT(four[1], four[2]) << "four views agree: green";
  EXPECT_GT(four[1], two[1]);
}

}  // namespace
}  // namespace reconduit
