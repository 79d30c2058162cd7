#include "core/feature/affine_features.h"

#include "core/feature/matcher.h"
#include "core/feature/sift.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>

namespace reconduit {
namespace {

// Blurred noise at several scales plus random shapes, smaller than the picture so that a
// warped copy keeps all of it in view.
cv::Mat TexturedPanel(int width, int height, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat image(height, width, CV_32F, cv::Scalar(0));
  for (int octave = 0; octave < 4; ++octave) {
    const int step = 4 << octave;
    cv::Mat noise(height / step + 2, width / step + 2, CV_32F);
    rng.fill(noise, cv::RNG::UNIFORM, -1.0, 1.0);
    cv::Mat up;
    cv::resize(noise, up, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
    image += up * (40.0 / (octave + 1));
  }
  image += 128;
  cv::Mat out;
  image.convertTo(out, CV_8U);
  for (int i = 0; i < 200; ++i) {
    const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
    const int r = rng.uniform(3, 20);
    const cv::Scalar colour(rng.uniform(0, 256));
    if (i % 2 == 0) {
      cv::circle(out, c, r, colour, cv::FILLED, cv::LINE_AA);
    } else {
      cv::rectangle(out, cv::Rect(c.x, c.y, r, r * 2 / 3 + 1), colour, cv::FILLED);
    }
  }
  return out;
}

// Matches (ratio 0.8, mutual) whose positions agree with the true homography within 2 px.
int CorrectMatches(const FeatureSet& a, const FeatureSet& b, const cv::Matx33d& H) {
  const std::vector<FeatureMatch> matches =
      MatchDescriptors(ToDescriptorMatrix(a), ToDescriptorMatrix(b), MatchingOptions());
  int correct = 0;
  for (const FeatureMatch& m : matches) {
    const Keypoint& p = a.keypoints[m.index1];
    const Keypoint& q = b.keypoints[m.index2];
    const cv::Vec3d x = H * cv::Vec3d(p.x, p.y, 1.0);
    if (std::hypot(x[0] / x[2] - q.x, x[1] / x[2] - q.y) < 2.0) ++correct;
  }
  return correct;
}

TEST(AffineFeatureOptions, DefaultsAreValidAndBadValuesNamed) {
  std::string error;
  EXPECT_TRUE(AffineFeatureOptions().Check(&error)) << error;
  AffineFeatureOptions bad;
  bad.max_tilt = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("max_tilt"), std::string::npos);
  bad = AffineFeatureOptions();
  bad.duplicate_radius_px = -1;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("duplicate_radius_px"), std::string::npos);
}

// A textured panel seen head-on and from ~70 deg to the side (a squeeze of 3 with some
// perspective): SIFT's descriptors no longer match across such a tilt, ASIFT's do.
TEST(AffineFeatures, MatchAcrossAStrongTiltWherePlainSiftFails) {
  const int width = 400, height = 300;
  cv::Mat frontal(height, width, CV_8U, cv::Scalar(90));
  TexturedPanel(250, 250, 7).copyTo(frontal(cv::Rect(75, 25, 250, 250)));
  const cv::Point2f from[4] = {{75, 25}, {325, 25}, {325, 275}, {75, 275}};
  const cv::Point2f to[4] = {{158, 12}, {241, 37}, {241, 262}, {158, 287}};
  const cv::Matx33d H = cv::getPerspectiveTransform(from, to);
  cv::Mat tilted;
  cv::warpPerspective(frontal, tilted, cv::Mat(H), frontal.size(), cv::INTER_AREA,
                      cv::BORDER_CONSTANT, cv::Scalar(90));

  const SiftOptions sift;
  const int plain =
      CorrectMatches(ExtractSiftFeatures(frontal, sift), ExtractSiftFeatures(tilted, sift), H);
  const AffineFeatureOptions options;
  const FeatureSet a = ExtractAffineFeatures(frontal, options, frontal.size());
  const FeatureSet b = ExtractAffineFeatures(tilted, options, tilted.size());
  const int affine = CorrectMatches(a, b, H);
  std::printf("correct matches across a tilt of 3: SIFT %d, ASIFT %d (%zu and %zu keypoints)\n",
              plain, affine, a.size(), b.size());
  EXPECT_GE(affine, 60);
  EXPECT_GE(affine, 3 * std::max(plain, 1));

  // Strongest first, descriptors one row per keypoint, no two keypoints within 1 px.
  ASSERT_EQ(a.descriptors.rows, static_cast<int>(a.size()));
  for (std::size_t i = 1; i < a.size(); ++i) {
    EXPECT_GE(a.keypoints[i - 1].response, a.keypoints[i].response);
  }
  EXPECT_EQ(DropDuplicateKeypoints(a.keypoints, options.duplicate_radius_px).size(), a.size());
  // Deterministic.
  const FeatureSet again = ExtractAffineFeatures(frontal, options, frontal.size());
  ASSERT_EQ(again.size(), a.size());
  EXPECT_EQ(cv::norm(again.descriptors, a.descriptors, cv::NORM_L1), 0.0);
}

// Keypoints come back in the original's pixels when detected on a smaller working copy.
TEST(AffineFeatures, ReportsOriginalPixelsFromAWorkingCopy) {
  const cv::Mat big = TexturedPanel(640, 480, 3);
  AffineFeatureOptions options;
  options.max_tilt = 2;
  options.max_image_side = 320;
  cv::Mat half;
  cv::resize(big, half, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
  const FeatureSet from_big = ExtractAffineFeatures(big, options, big.size());
  const FeatureSet from_half = ExtractAffineFeatures(half, options, big.size());
  ASSERT_GT(from_big.size(), 100u);
  EXPECT_EQ(from_big.image_width, 640);
  EXPECT_EQ(from_half.image_height, 480);
  float max_x = 0;
  for (const Keypoint& kp : from_half.keypoints) max_x = std::max(max_x, kp.x);
  EXPECT_GT(max_x, 500.0f);  // Reported at full size, not at 320 px.
  EXPECT_EQ(from_big.size(), from_half.size());
}

Keypoint At(float x, float y, float response) {
  Keypoint kp;
  kp.x = x;
  kp.y = y;
  kp.response = response;
  return kp;
}

TEST(DropDuplicateKeypoints, KeepsTheStrongestWithinTheRadius) {
  const std::vector<Keypoint> keypoints = {At(10, 10, 0.1f), At(10.5f, 10, 0.3f), At(12, 10, 0.2f),
                                           At(10.2f, 10.8f, 0.05f), At(-3, -3, 0.01f)};
  // 1 (strongest) removes 0 and 3 (within 1 px); 2 is 1.5 px from 1; 4 is far.
  EXPECT_EQ(DropDuplicateKeypoints(keypoints, 1.0), (std::vector<int>{1, 2, 4}));
  EXPECT_EQ(DropDuplicateKeypoints(keypoints, 0.0), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(DropDuplicateKeypoints(keypoints, 3.0), (std::vector<int>{1, 4}));
}

TEST(MergeKeypoints, NearOnesTakeTheNearestBaseIndexOthersAreAppended) {
  const std::vector<Keypoint> base = {At(0, 0, 1), At(5, 0, 1), At(100, 100, 1)};
  const std::vector<Keypoint> extra = {At(4.6f, 0.2f, 1), At(50, 50, 1), At(0.3f, 0, 1),
                                       At(100, 101.5f, 1), At(2.5f, 0, 1)};
  std::vector<Keypoint> appended;
  const std::vector<int> index = MergeKeypoints(base, extra, 1.0, &appended);
  EXPECT_EQ(index, (std::vector<int>{1, 3, 0, 4, 5}));
  ASSERT_EQ(appended.size(), 3u);
  EXPECT_EQ(appended[0].x, 50.0f);
  EXPECT_EQ(appended[1].y, 101.5f);
  EXPECT_EQ(appended[2].x, 2.5f);
  // Across cell borders: the nearest of two candidates in neighbouring cells.
  std::vector<Keypoint> more;
  EXPECT_EQ(MergeKeypoints({At(0.95f, 0, 1), At(1.9f, 0, 1)}, {At(1.5f, 0, 1)}, 1.0, &more),
            (std::vector<int>{1}));
  EXPECT_TRUE(more.empty());
}

}  // namespace
}  // namespace reconduit
