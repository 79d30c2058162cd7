#include "core/feature/sift.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>

namespace reconduit {
namespace {

// A deterministic textured picture: blurred noise at several scales plus random shapes, so
// SIFT has blobs and corners everywhere.
cv::Mat TexturedImage(int width, int height, std::uint64_t seed) {
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
  for (int i = 0; i < 300; ++i) {
    const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
    const int r = rng.uniform(3, 25);
    const cv::Scalar colour(rng.uniform(0, 256));
    if (i % 2 == 0) {
      cv::circle(out, c, r, colour, cv::FILLED, cv::LINE_AA);
    } else {
      cv::rectangle(out, cv::Rect(c.x, c.y, r, r * 2 / 3 + 1), colour, cv::FILLED);
    }
  }
  return out;
}

TEST(SiftOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(SiftOptions().Check(&error)) << error;
  SiftOptions bad;
  bad.spread_fraction = 1.5;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("spread_fraction"), std::string::npos);
}

TEST(SiftOptions, MaxFeaturesRangeIsTheOptionTables) {
  SiftOptions options;
  EXPECT_EQ(options.max_features, kDefaultMaxFeatures);
  std::string error;
  for (const int value : {kMinMaxFeatures, kMaxMaxFeatures}) {
    options.max_features = value;
    EXPECT_TRUE(options.Check(&error)) << error;
  }
  for (const int value : {kMinMaxFeatures - 1, kMaxMaxFeatures + 1}) {
    options.max_features = value;
    EXPECT_FALSE(options.Check(&error)) << value;
    EXPECT_NE(error.find("max_features must be in [256, 65536]"), std::string::npos) << error;
  }
}

TEST(SelectSpreadKeypoints, KeepsAllWhenUnderBudget) {
  std::vector<cv::KeyPoint> candidates = {cv::KeyPoint(1, 1, 2, 0, 0.1f),
                                          cv::KeyPoint(5, 5, 2, 0, 0.3f)};
  const auto chosen = SelectSpreadKeypoints(candidates, 10, 10, 5, 0.3, 4);
  ASSERT_EQ(chosen.size(), 2u);
  EXPECT_EQ(chosen[0], 1) << "strongest first";
}

TEST(SelectSpreadKeypoints, StrongestPlusEveryCellCovered) {
  // 5000 strong candidates crowd the top-left corner; 2 weak ones sit in every cell.
  std::vector<cv::KeyPoint> candidates;
  cv::RNG rng(1);
  for (int i = 0; i < 5000; ++i) {
    candidates.emplace_back(rng.uniform(0.f, 100.f), rng.uniform(0.f, 100.f), 2.f, 0.f,
                            rng.uniform(0.5f, 1.0f));
  }
  const int width = 800, height = 600, cells = 8;  // 100 px cells: 8 x 6.
  for (int cy = 0; cy < 6; ++cy) {
    for (int cx = 0; cx < 8; ++cx) {
      for (int k = 0; k < 2; ++k) {
        candidates.emplace_back(cx * 100.f + 50.f + k, cy * 100.f + 50.f, 2.f, 0.f,
                                0.01f + 0.001f * k);
      }
    }
  }
  const auto chosen = SelectSpreadKeypoints(candidates, width, height, 1000, 0.3, cells);
  ASSERT_EQ(chosen.size(), 1000u);
  EXPECT_EQ(std::set<int>(chosen.begin(), chosen.end()).size(), 1000u) << "no duplicates";
  // The first 700 are the strongest candidates overall.
  float weakest_strong = 1.0f;
  for (int i = 0; i < 700; ++i)
    weakest_strong = std::min(weakest_strong, candidates[chosen[i]].response);
  int stronger_left_out = 0;
  std::set<int> in(chosen.begin(), chosen.end());
  for (int i = 0; i < 5000; ++i) {
    if (!in.count(i) && candidates[i].response > weakest_strong) ++stronger_left_out;
  }
  EXPECT_EQ(stronger_left_out, 0);
  // Every cell got at least one feature.
  std::set<int> covered;
  for (int index : chosen) {
    covered.insert(static_cast<int>(candidates[index].pt.y / 100) * 8 +
                   static_cast<int>(candidates[index].pt.x / 100));
  }
  EXPECT_EQ(covered.size(), 48u);
}

TEST(ToRootSiftBytes, UnitNormAfterDequantisation) {
  cv::Mat sift(3, 128, CV_32F);
  cv::RNG(7).fill(sift, cv::RNG::UNIFORM, 0.0, 100.0);
  const cv::Mat bytes = ToRootSiftBytes(sift);
  ASSERT_EQ(bytes.type(), CV_8U);
  for (int r = 0; r < 3; ++r) {
    double norm2 = 0.0;
    for (int c = 0; c < 128; ++c) norm2 += std::pow(bytes.at<std::uint8_t>(r, c) / 512.0, 2);
    EXPECT_NEAR(std::sqrt(norm2), 1.0, 0.01);
  }
}

// Detects in an image and in a copy warped by a known homography, matches with the ratio
// test, and checks that the matches agree with the homography: this pins the coordinate
// convention (including the scaling back from the working resolution) and the descriptors.
void CheckRepeatableUnderHomography(int max_image_side,
                                    double tolerance_px,
                                    int max_tile_pixels = 1 << 30) {
  const cv::Mat image = TexturedImage(1200, 900, 42);
  cv::Mat h = cv::getRotationMatrix2D(cv::Point2f(600, 450), 20.0, 0.8);
  h.push_back(cv::Mat((cv::Mat_<double>(1, 3) << 0, 0, 1)));
  cv::Mat warped;
  cv::warpPerspective(image, warped, h, image.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);

  SiftOptions options;
  options.max_image_side = max_image_side;
  options.max_features = 4000;
  options.max_tile_pixels = max_tile_pixels;
  const FeatureSet f1 = ExtractSiftFeatures(image, options);
  const FeatureSet f2 = ExtractSiftFeatures(warped, options);
  ASSERT_GT(f1.size(), 1000u);
  ASSERT_EQ(f1.descriptors.rows, static_cast<int>(f1.size()));
  EXPECT_EQ(f1.image_width, 1200);
  for (const Keypoint& kp : f1.keypoints) {
    ASSERT_GE(kp.x, -0.5f);
    ASSERT_LT(kp.x, 1199.5f);
  }

  cv::Mat d1, d2;
  f1.descriptors.convertTo(d1, CV_32F);
  f2.descriptors.convertTo(d2, CV_32F);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(cv::NORM_L2).knnMatch(d1, d2, knn, 2);
  int matches = 0, correct = 0;
  for (const auto& m : knn) {
    if (m.size() < 2 || m[0].distance > 0.8f * m[1].distance) continue;
    ++matches;
    const Keypoint& a = f1.keypoints[m[0].queryIdx];
    const Keypoint& b = f2.keypoints[m[0].trainIdx];
    const cv::Vec3d p = cv::Matx33d(h) * cv::Vec3d(a.x, a.y, 1.0);
    if (std::hypot(p[0] / p[2] - b.x, p[1] / p[2] - b.y) < tolerance_px) ++correct;
  }
  EXPECT_GT(matches, 300);
  EXPECT_GT(correct, 0.9 * matches) << correct << " of " << matches;
}

TEST(ExtractSiftFeatures, RepeatableUnderAKnownHomography) {
  CheckRepeatableUnderHomography(/*max_image_side=*/3200, /*tolerance_px=*/1.5);
}

TEST(ExtractSiftFeatures, RepeatableUnderAKnownHomographyInTiles) {
  CheckRepeatableUnderHomography(/*max_image_side=*/3200, /*tolerance_px=*/1.5,
                                 /*max_tile_pixels=*/500000);
}

TEST(ExtractSiftFeatures, DownscaledDetectionReportsOriginalPixels) {
  CheckRepeatableUnderHomography(/*max_image_side=*/600, /*tolerance_px=*/3.0);
}

// Gaussian blobs at known sub-pixel centres: keypoints must sit on them without bias, at
// full resolution and when detection runs on a downscaled copy.
void CheckBlobCentres(int max_image_side,
                      double tolerance_px,
                      int max_tile_pixels = 1 << 30,
                      double min_blob_sigma = 2.0,
                      double max_blob_sigma = 4.5,
                      bool upsampled = false) {
  const int width = 800, height = 600;
  cv::RNG rng(11);
  cv::Mat image(height, width, CV_32F, cv::Scalar(60));
  std::vector<cv::Point2d> centres;
  for (int gy = 0; gy < 9; ++gy) {
    for (int gx = 0; gx < 12; ++gx) {
      const cv::Point2d c(40 + 64 * gx + rng.uniform(0.0, 1.0),
                          40 + 64 * gy + rng.uniform(0.0, 1.0));
      const double sigma = rng.uniform(min_blob_sigma, max_blob_sigma);
      centres.push_back(c);
      for (int y = static_cast<int>(c.y) - 24; y <= static_cast<int>(c.y) + 24; ++y) {
        for (int x = static_cast<int>(c.x) - 24; x <= static_cast<int>(c.x) + 24; ++x) {
          const double d2 = (x - c.x) * (x - c.x) + (y - c.y) * (y - c.y);
          image.at<float>(y, x) += static_cast<float>(150.0 * std::exp(-d2 / (2 * sigma * sigma)));
        }
      }
    }
  }
  cv::Mat bytes;
  image.convertTo(bytes, CV_8U);
  SiftOptions options;
  options.max_image_side = max_image_side;
  options.max_tile_pixels = max_tile_pixels;
  // 108 blobs: far fewer candidates than min_features, which makes the 800 x 600 picture be
  // detected again at twice its size when `upsampled`, and never otherwise.
  if (!upsampled) options.min_features = 0;
  SiftDetection detection;
  const FeatureSet features = ExtractSiftFeatures(bytes, options, bytes.size(), &detection);
  EXPECT_EQ(detection.upsampled, upsampled);

  double sum_dx = 0.0, sum_dy = 0.0;
  int found = 0;
  for (const cv::Point2d& c : centres) {
    const Keypoint* nearest = nullptr;
    double best = 1.5;
    for (const Keypoint& kp : features.keypoints) {
      const double d = std::hypot(kp.x - c.x, kp.y - c.y);
      if (d < best) {
        best = d;
        nearest = &kp;
      }
    }
    if (nearest == nullptr) continue;
    sum_dx += nearest->x - c.x;
    sum_dy += nearest->y - c.y;
    ++found;
  }
  ASSERT_GT(found, 0.75 * centres.size());
  EXPECT_NEAR(sum_dx / found, 0.0, tolerance_px);
  EXPECT_NEAR(sum_dy / found, 0.0, tolerance_px);
}

TEST(ExtractSiftFeatures, BlobCentresWithoutBias) {
  CheckBlobCentres(/*max_image_side=*/3200, /*tolerance_px=*/0.03);
}

TEST(ExtractSiftFeatures, BlobCentresWithoutBiasWhenDownscaled) {
  CheckBlobCentres(/*max_image_side=*/400, /*tolerance_px=*/0.06);
}

// In tiles: small blobs from the pieces, large ones (found at coarse octaves) from the 4x
// smaller copy, whose pixel centres must map back without a shift.
TEST(ExtractSiftFeatures, BlobCentresWithoutBiasInTiles) {
  CheckBlobCentres(/*max_image_side=*/3200, /*tolerance_px=*/0.03, kMinSiftTilePixels);
  CheckBlobCentres(/*max_image_side=*/3200, /*tolerance_px=*/0.06, kMinSiftTilePixels,
                   /*min_blob_sigma=*/6.0, /*max_blob_sigma=*/8.0);
}

// Detected at twice the size (few candidates, a small picture): keypoints still sit on the
// blobs in the picture's own pixels.
TEST(ExtractSiftFeatures, BlobCentresWithoutBiasWhenUpsampled) {
  CheckBlobCentres(/*max_image_side=*/3200, /*tolerance_px=*/0.03, 1 << 30, 2.0, 4.5,
                   /*upsampled=*/true);
}

// A dim copy of a textured picture (contrast a seventh, as an underexposed photo): detected
// once at the usual threshold it yields a few hundred keypoints; detected again at lower
// thresholds, many more, as repeatable under a known homography as those of the bright
// original.
TEST(ExtractSiftFeatures, DimPictureIsDetectedAgainAtLowerContrast) {
  const cv::Mat bright = TexturedImage(1200, 900, 42);
  cv::Mat dim;
  bright.convertTo(dim, CV_8U, 1.0 / 7.0, 20.0);
  cv::Mat h = cv::getRotationMatrix2D(cv::Point2f(600, 450), 20.0, 0.8);
  h.push_back(cv::Mat((cv::Mat_<double>(1, 3) << 0, 0, 1)));
  cv::Mat warped;
  cv::warpPerspective(dim, warped, h, dim.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);

  SiftOptions once;
  once.min_features = 0;
  SiftDetection detection;
  const FeatureSet plain = ExtractSiftFeatures(dim, once, dim.size(), &detection);
  EXPECT_EQ(detection.passes, 1);
  const SiftOptions options;
  const FeatureSet f1 = ExtractSiftFeatures(dim, options, dim.size(), &detection);
  std::printf("dim picture: %zu keypoints detected once, %zu after %d passes (contrast %.4f)\n",
              plain.size(), f1.size(), detection.passes, detection.contrast_threshold);
  EXPECT_GT(detection.passes, 1);
  EXPECT_LT(detection.contrast_threshold, options.contrast_threshold);
  EXPECT_FALSE(detection.upsampled);  // 1200 px: above upsample_below_side.
  EXPECT_GT(f1.size(), 2 * plain.size());

  // The bright original is detected once.
  ExtractSiftFeatures(bright, options, bright.size(), &detection);
  EXPECT_EQ(detection.passes, 1);

  const FeatureSet f2 = ExtractSiftFeatures(warped, options);
  cv::Mat d1, d2;
  f1.descriptors.convertTo(d1, CV_32F);
  f2.descriptors.convertTo(d2, CV_32F);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(cv::NORM_L2).knnMatch(d1, d2, knn, 2);
  int matches = 0, correct = 0;
  for (const auto& m : knn) {
    if (m.size() < 2 || m[0].distance > 0.8f * m[1].distance) continue;
    ++matches;
    const Keypoint& a = f1.keypoints[m[0].queryIdx];
    const Keypoint& b = f2.keypoints[m[0].trainIdx];
    const cv::Vec3d p = cv::Matx33d(h) * cv::Vec3d(a.x, a.y, 1.0);
    if (std::hypot(p[0] / p[2] - b.x, p[1] / p[2] - b.y) < 1.5) ++correct;
  }
  EXPECT_GT(matches, 300);
  EXPECT_GT(correct, 0.9 * matches) << correct << " of " << matches;
}

TEST(SiftOptions, ChecksTheFewFeatureSettings) {
  std::string error;
  SiftOptions options;
  options.min_features = kMaxMaxFeatures;  // Above max_features: asks for max_features.
  EXPECT_TRUE(options.Check(&error)) << error;
  options.min_features = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_features"), std::string::npos) << error;
  options = SiftOptions();
  options.min_contrast_threshold = 2 * options.contrast_threshold;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_contrast_threshold"), std::string::npos) << error;
  options = SiftOptions();
  options.upsample_below_side = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("upsample_below_side"), std::string::npos) << error;
}

TEST(ExtractSiftFeatures, Deterministic) {
  const cv::Mat image = TexturedImage(400, 300, 3);
  const FeatureSet a = ExtractSiftFeatures(image, SiftOptions());
  const FeatureSet b = ExtractSiftFeatures(image, SiftOptions());
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_L1), 0.0);
}

TEST(ExtractSiftFeatures, FlatImageHasNoFeatures) {
  const FeatureSet f = ExtractSiftFeatures(cv::Mat(200, 200, CV_8U, cv::Scalar(90)), SiftOptions());
  EXPECT_EQ(f.size(), 0u);
  EXPECT_EQ(f.descriptors.rows, 0);
}

TEST(ExtractSiftFeatures, RejectsEmptyImage) {
  EXPECT_THROW(ExtractSiftFeatures(cv::Mat(), SiftOptions()), CheckError);
}

}  // namespace
}  // namespace reconduit

namespace reconduit {
namespace {

// A photo read at its working size (image_reader.h) and described with its original size gives
// the features of the full photo: same size, keypoints in the original's pixels.
TEST(ExtractSiftFeatures, WorkingSizeCopyReportsOriginalPixels) {
  const cv::Mat full = TexturedImage(1600, 1200, 11);
  SiftOptions options;
  options.max_image_side = 400;
  const FeatureSet reference = ExtractSiftFeatures(full, options);
  cv::Mat working;
  cv::resize(full, working, cv::Size(400, 300), 0, 0, cv::INTER_AREA);
  const FeatureSet features = ExtractSiftFeatures(working, options, full.size());
  EXPECT_EQ(features.image_width, 1600);
  EXPECT_EQ(features.image_height, 1200);
  ASSERT_GT(features.size(), 100u);
  // The same detection: every keypoint lies where the full photo's does (same working image).
  ASSERT_EQ(features.size(), reference.size());
  for (std::size_t i = 0; i < features.size(); ++i) {
    EXPECT_NEAR(features.keypoints[i].x, reference.keypoints[i].x, 1e-3);
    EXPECT_NEAR(features.keypoints[i].y, reference.keypoints[i].y, 1e-3);
    EXPECT_NEAR(features.keypoints[i].scale, reference.keypoints[i].scale, 1e-3);
  }
  EXPECT_THROW(ExtractSiftFeatures(full, options, cv::Size(100, 100)), CheckError);
}

}  // namespace
}  // namespace reconduit

namespace reconduit {
namespace {

// The keypoints of `image` described whole and in tiles of `tile_pixels`.
struct WholeAndTiled {
  FeatureSet whole;
  FeatureSet tiled;
};

WholeAndTiled DescribeWholeAndTiled(const cv::Mat& image, int tile_pixels) {
  SiftOptions options;
  options.max_features = kMaxMaxFeatures;  // Every candidate: compare the detectors.
  options.max_tile_pixels = 1 << 30;
  WholeAndTiled result;
  result.whole = ExtractSiftFeatures(image, options);
  options.max_tile_pixels = tile_pixels;
  result.tiled = ExtractSiftFeatures(image, options);
  return result;
}

// The share of `a`'s keypoints of scale in [min_scale, max_scale) that `b` has within
// `tolerance_px`, at a scale within 2 %.
double ShareFound(const FeatureSet& a,
                  const FeatureSet& b,
                  double min_scale,
                  double max_scale,
                  double tolerance_px) {
  std::vector<cv::Point2f> points;
  for (const Keypoint& kp : b.keypoints) points.emplace_back(kp.x, kp.y);
  cv::flann::KDTreeIndexParams params(1);
  const cv::Mat data = cv::Mat(points).reshape(1);
  cv::flann::Index index(data, params);
  int total = 0, found = 0;
  for (const Keypoint& kp : a.keypoints) {
    if (kp.scale < min_scale || kp.scale >= max_scale) continue;
    ++total;
    std::vector<float> query = {kp.x, kp.y};
    std::vector<int> indices(8);
    std::vector<float> distances(8);
    index.knnSearch(query, indices, distances, 8, cv::flann::SearchParams(32));
    for (int k = 0; k < 8; ++k) {
      const Keypoint& other = b.keypoints[indices[k]];
      if (std::sqrt(distances[k]) <= tolerance_px &&
          std::abs(other.scale - kp.scale) <= 0.02 * kp.scale) {
        ++found;
        break;
      }
    }
  }
  return total == 0 ? 0.0 : static_cast<double>(found) / total;
}

TEST(ExtractSiftFeatures, TilesFindWhatTheWholeImageFinds) {
  const cv::Mat image = TexturedImage(1400, 1000, 5);
  const WholeAndTiled r = DescribeWholeAndTiled(image, /*tile_pixels=*/400000);
  ASSERT_GT(r.whole.size(), 3000u);
  const double fine = ShareFound(r.whole, r.tiled, 0.0, 6.5, 0.01);
  const double coarse = ShareFound(r.whole, r.tiled, 8.0, 1e9, 0.5);
  const double back = ShareFound(r.tiled, r.whole, 0.0, 1e9, 0.5);
  std::printf("whole %zu, tiled %zu; fine found %.4f, coarse %.4f, tiled in whole %.4f\n",
              r.whole.size(), r.tiled.size(), fine, coarse, back);
  // The two finest octaves come from the same pixels: the same keypoints (measured: all).
  EXPECT_GT(fine, 0.99);
  // Coarser ones come from the 4x smaller copy's pyramid, not from the decimated one:
  // measured 59 % of them within 0.5 px and 2 % in scale (the rest nearby or not detected).
  EXPECT_GT(coarse, 0.5);
  // Nearly every keypoint of the pieces is one the whole image has (measured 98.4 %).
  EXPECT_GT(back, 0.95);
}

}  // namespace
}  // namespace reconduit
