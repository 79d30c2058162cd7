#include "core/mvs/image_noise.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <random>

namespace reconduit {
namespace {

cv::Mat WithNoise(const cv::Mat& clean, double stddev, std::uint64_t seed) {
  cv::Mat noisy = clean.clone();
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> gauss(0.0f, static_cast<float>(stddev));
  for (auto it = noisy.begin<float>(); it != noisy.end<float>(); ++it) *it += gauss(rng);
  return noisy;
}

// A smooth ramp and a quadratic bowl: the filter cancels both, so only the noise is measured.
cv::Mat SmoothImage(int width, int height) {
  cv::Mat image(height, width, CV_32FC1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double u = x - width / 2.0, v = y - height / 2.0;
      image.at<float>(y, x) = static_cast<float>(60.0 + 0.2 * x + 1e-4 * (u * u + v * v));
    }
  }
  return image;
}

TEST(ImageNoise, RecoversWhiteNoiseOnASmoothImage) {
  const cv::Mat clean = SmoothImage(640, 480);
  EXPECT_LT(EstimateNoiseStddev(clean), 0.05);
  for (double sigma : {0.5, 2.0, 5.0}) {
    const double estimate = EstimateNoiseStddev(WithNoise(clean, sigma, 3));
    // The flattest tenth of 1 200 blocks of 256 pixels: a few per cent low.
    EXPECT_NEAR(estimate, sigma, 0.08 * sigma) << "sigma " << sigma;
    EXPECT_LE(estimate, sigma * 1.01) << "sigma " << sigma;
  }
}

// Strong texture over most of the photo and a plain region over a fifth of it: the estimate
// is that of the plain part, where Immerkær's whole-image mean would count the texture.
TEST(ImageNoise, TextureDoesNotCountAsNoise) {
  const int width = 640, height = 480;
  cv::Mat image(height, width, CV_32FC1);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> texture(40.0f, 200.0f);
  for (auto it = image.begin<float>(); it != image.end<float>(); ++it) *it = texture(rng);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  image(cv::Rect(0, 0, width, height / 5)).setTo(120.0f);
  const cv::Mat noisy = WithNoise(image, 2.0, 9);
  EXPECT_NEAR(EstimateNoiseStddev(noisy), 2.0, 0.2);
  NoiseEstimateOptions whole;
  whole.percentile = 0.5;  // Most blocks are textured: no longer the noise.
  EXPECT_GT(EstimateNoiseStddev(noisy, whole), 4.0);
}

// A clipped black background has no response at all and must not pull the estimate to 0.
TEST(ImageNoise, ClippedBlocksAreSkipped) {
  cv::Mat image = WithNoise(SmoothImage(320, 240), 3.0, 11);
  image(cv::Rect(0, 0, 320, 160)).setTo(0.0f);
  EXPECT_NEAR(EstimateNoiseStddev(image), 3.0, 0.3);
  cv::Mat eight_bit;
  image.convertTo(eight_bit, CV_8UC1);  // Rounding adds 1 / sqrt(12) grey levels.
  EXPECT_NEAR(EstimateNoiseStddev(eight_bit), std::hypot(3.0, 0.29), 0.3);
}

TEST(ImageNoise, SmallOrFlatImagesGiveZero) {
  EXPECT_EQ(EstimateNoiseStddev(cv::Mat(10, 10, CV_32FC1, cv::Scalar(5))), 0.0);
  EXPECT_EQ(EstimateNoiseStddev(cv::Mat(100, 100, CV_8UC1, cv::Scalar(255))), 0.0);
  EXPECT_THROW(EstimateNoiseStddev(cv::Mat(100, 100, CV_32FC3)), CheckError);
  NoiseEstimateOptions bad;
  bad.block_size = 2;
  EXPECT_THROW(EstimateNoiseStddev(cv::Mat(100, 100, CV_32FC1), bad), CheckError);
}

}  // namespace
}  // namespace reconduit
