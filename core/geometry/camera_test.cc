#include "core/geometry/camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace reconduit {
namespace {

Camera TestCamera(double k1, double k2) {
  Camera camera = Camera::FromFocal(640, 480, 500.0);
  camera.cx = 322.25;  // Off-centre on purpose, so cx/cy mix-ups show.
  camera.cy = 236.75;
  camera.k1 = k1;
  camera.k2 = k2;
  return camera;
}

// Distortions that are monotone over the whole 640x480 image at f = 500 (corner radius in
// normalised coordinates ~0.82), of both signs and both orders.
std::vector<Camera> DistortedCameras() {
  return {TestCamera(0.0, 0.0),    TestCamera(0.1, 0.0),    TestCamera(-0.2, 0.0),
          TestCamera(0.0, 0.08),   TestCamera(0.0, -0.1),   TestCamera(-0.25, 0.06),
          TestCamera(0.15, -0.05), TestCamera(-0.1, -0.05), TestCamera(0.2, 0.1)};
}

// Pixels on a grid covering the whole image including its borders and corners.
std::vector<Eigen::Vector2d> ImageGrid(const Camera& camera) {
  std::vector<Eigen::Vector2d> pixels;
  for (int i = 0; i <= 16; ++i) {
    for (int j = 0; j <= 12; ++j) {
      pixels.emplace_back(-0.5 + camera.width * i / 16.0, -0.5 + camera.height * j / 12.0);
    }
  }
  return pixels;
}

TEST(Camera, FromFocalPutsPrincipalPointAtImageCentre) {
  const Camera camera = Camera::FromFocal(640, 480, 500.0);
  EXPECT_EQ(camera.width, 640);
  EXPECT_EQ(camera.height, 480);
  EXPECT_EQ(camera.focal, 500.0);
  EXPECT_EQ(camera.cx, 319.5);
  EXPECT_EQ(camera.cy, 239.5);
  EXPECT_EQ(camera.k1, 0.0);
  EXPECT_EQ(camera.k2, 0.0);
}

TEST(Camera, IntrinsicMatrix) {
  const Camera camera = TestCamera(0.1, 0.2);
  Eigen::Matrix3d expected;
  expected << 500, 0, 322.25, 0, 500, 236.75, 0, 0, 1;
  EXPECT_EQ(camera.K(), expected);
  // K maps camera coordinates to homogeneous pixels for a distortion-free camera.
  const Camera pinhole = TestCamera(0.0, 0.0);
  const Eigen::Vector3d point(0.3, -0.2, 2.5);
  const Eigen::Vector2d pixel = (pinhole.K() * point).hnormalized();
  EXPECT_LT((pixel - *pinhole.ImgFromCam(point)).norm(), 1e-12);
}

TEST(Camera, ProjectsKnownPoint) {
  Camera camera = TestCamera(0.0, 0.0);
  // x = 0.4 / 2 = 0.2, y = -0.1 / 2 = -0.05.
  Eigen::Vector2d pixel = *camera.ImgFromCam({0.4, -0.1, 2.0});
  EXPECT_NEAR(pixel.x(), 500 * 0.2 + 322.25, 1e-12);
  EXPECT_NEAR(pixel.y(), 500 * -0.05 + 236.75, 1e-12);
  camera.k1 = 0.1;
  camera.k2 = -0.02;
  const double r2 = 0.2 * 0.2 + 0.05 * 0.05;
  const double factor = 1.0 + 0.1 * r2 - 0.02 * r2 * r2;
  pixel = *camera.ImgFromCam({0.4, -0.1, 2.0});
  EXPECT_NEAR(pixel.x(), 500 * 0.2 * factor + 322.25, 1e-12);
  EXPECT_NEAR(pixel.y(), 500 * -0.05 * factor + 236.75, 1e-12);
}

TEST(Camera, PixelToRayToPixelRoundTripOverWholeImage) {
  for (const Camera& camera : DistortedCameras()) {
    for (const Eigen::Vector2d& pixel : ImageGrid(camera)) {
      const auto ray = camera.CamFromImg(pixel);
      ASSERT_TRUE(ray.has_value()) << camera << " pixel " << pixel.transpose();
      EXPECT_EQ(ray->z(), 1.0);
      const auto back = camera.ImgFromCam(*ray * 3.7);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((*back - pixel).norm(), 1e-9) << camera << " pixel " << pixel.transpose();
    }
  }
}

TEST(Camera, PointToPixelToRayRoundTrip) {
  for (const Camera& camera : DistortedCameras()) {
    for (const Eigen::Vector2d& pixel : ImageGrid(camera)) {
      // A point whose projection lands near `pixel`, at depth 4.2.
      const Eigen::Vector3d point =
          4.2 * Eigen::Vector2d(camera.NormalizedFromPixel(pixel) * 0.9).homogeneous();
      const auto projected = camera.ImgFromCam(point);
      ASSERT_TRUE(projected.has_value());
      const auto ray = camera.CamFromImg(*projected);
      ASSERT_TRUE(ray.has_value());
      EXPECT_LT((*ray * point.z() - point).norm(), 1e-10) << camera;
    }
  }
}

TEST(Camera, DistortUndistortRoundTrip) {
  for (const Camera& camera : DistortedCameras()) {
    for (double x = -0.8; x <= 0.8; x += 0.05) {
      for (double y = -0.6; y <= 0.6; y += 0.05) {
        const Eigen::Vector2d normalized(x, y);
        const auto undistorted = camera.Undistort(camera.Distort(normalized));
        ASSERT_TRUE(undistorted.has_value()) << camera;
        EXPECT_LT((*undistorted - normalized).norm(), 1e-10) << camera << " at " << x << ", " << y;
      }
    }
  }
}

TEST(Camera, DistortionDirectionFollowsSignOfK1) {
  const Eigen::Vector2d normalized(0.3, 0.4);                        // r = 0.5.
  EXPECT_GT(TestCamera(0.1, 0.0).Distort(normalized).norm(), 0.5);   // Pincushion.
  EXPECT_LT(TestCamera(-0.1, 0.0).Distort(normalized).norm(), 0.5);  // Barrel.
  EXPECT_EQ(TestCamera(0.0, 0.0).Distort(normalized), normalized);
  // The direction is kept.
  const Eigen::Vector2d distorted = TestCamera(-0.3, 0.1).Distort(normalized);
  EXPECT_NEAR(distorted.normalized().dot(normalized.normalized()), 1.0, 1e-15);
}

TEST(Camera, UndistortOfOriginIsOrigin) {
  const auto undistorted = TestCamera(-0.3, 0.1).Undistort(Eigen::Vector2d::Zero());
  ASSERT_TRUE(undistorted.has_value());
  EXPECT_EQ(*undistorted, Eigen::Vector2d::Zero());
}

TEST(Camera, UndistortFailsBeyondFoldRadius) {
  // k1 = -0.5: r_d(r) = r (1 - 0.5 r²) peaks at r = sqrt(2/3), where r_d = sqrt(2/3) * 2/3.
  const Camera camera = TestCamera(-0.5, 0.0);
  const double r_fold = std::sqrt(2.0 / 3.0);
  const double rd_max = r_fold * 2.0 / 3.0;
  const Eigen::Vector2d direction = Eigen::Vector2d(3.0, -4.0).normalized();
  EXPECT_FALSE(camera.Undistort(direction * (rd_max + 1e-6)).has_value());
  EXPECT_FALSE(camera.Undistort(direction * 2.0).has_value());
  EXPECT_FALSE(camera.CamFromImg(camera.PixelFromNormalized(direction * 0.6)).has_value());

  // Just inside the fold, the inverse exists and is the branch below the fold radius.
  const auto inside = camera.Undistort(direction * (rd_max * 0.999));
  ASSERT_TRUE(inside.has_value());
  EXPECT_LT(inside->norm(), r_fold);
  EXPECT_NEAR(camera.Distort(*inside).norm(), rd_max * 0.999, 1e-12);

  // A point beyond the fold distorts back inside it; Undistort returns the other preimage.
  const Eigen::Vector2d beyond = direction * 1.1;
  const auto other = camera.Undistort(camera.Distort(beyond));
  ASSERT_TRUE(other.has_value());
  EXPECT_LT(other->norm(), r_fold);
  EXPECT_LT((camera.Distort(*other) - camera.Distort(beyond)).norm(), 1e-12);
}

TEST(Camera, UndistortFailsBeyondFoldWithNegativeK2) {
  // k1 = 0, k2 = -0.2: r_d' = 1 - r⁴ = 0 at r = 1, r_d(1) = 0.8.
  const Camera camera = TestCamera(0.0, -0.2);
  EXPECT_FALSE(camera.Undistort({0.81, 0.0}).has_value());
  const auto inside = camera.Undistort({0.0, 0.79});
  ASSERT_TRUE(inside.has_value());
  EXPECT_LT(inside->norm(), 1.0);
  EXPECT_NEAR(camera.Distort(*inside).y(), 0.79, 1e-12);
}

TEST(Camera, PositiveDistortionUndistortsEverywhere) {
  const Camera camera = TestCamera(0.3, 0.2);
  for (const double rd : {1e-8, 0.5, 2.0, 10.0, 1e3}) {
    const auto undistorted = camera.Undistort({rd, 0.0});
    ASSERT_TRUE(undistorted.has_value()) << rd;
    EXPECT_NEAR(camera.Distort(*undistorted).x(), rd, 1e-12 * std::max(1.0, rd));
  }
}

TEST(Camera, PointsBehindOrOnCameraPlaneDoNotProject) {
  const Camera camera = TestCamera(0.1, 0.0);
  EXPECT_FALSE(camera.ImgFromCam({0.0, 0.0, 0.0}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({0.1, 0.2, 0.0}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({0.0, 0.0, -1.0}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({0.1, -0.3, -1e-9}).has_value());
  EXPECT_FALSE(camera.ImgFromCam({0.0, 0.0, std::nan("")}).has_value());
  EXPECT_TRUE(camera.ImgFromCam({0.0, 0.0, 1e-9}).has_value());
}

TEST(Camera, PrincipalPointProjectsFromOpticalAxis) {
  const Camera camera = TestCamera(-0.2, 0.05);
  const Eigen::Vector2d pixel = *camera.ImgFromCam({0.0, 0.0, 5.0});
  EXPECT_EQ(pixel, Eigen::Vector2d(camera.cx, camera.cy));
}

TEST(Camera, InImageUsesPixelEdges) {
  const Camera camera = Camera::FromFocal(4, 3, 10.0);
  EXPECT_TRUE(camera.InImage({-0.5, -0.5}));
  EXPECT_TRUE(camera.InImage({3.49, 2.49}));
  EXPECT_FALSE(camera.InImage({3.5, 1.0}));
  EXPECT_FALSE(camera.InImage({1.0, 2.5}));
  EXPECT_FALSE(camera.InImage({-0.51, 1.0}));
  EXPECT_FALSE(camera.InImage({1.0, -0.51}));
}

TEST(Camera, FieldOfView) {
  EXPECT_NEAR(Camera::FromFocal(640, 480, 320.0).FieldOfViewXDeg(), 90.0, 1e-12);
  EXPECT_NEAR(Camera::FromFocal(640, 480, 320.0 / std::sqrt(3.0)).FieldOfViewXDeg(), 120.0, 1e-12);
}

TEST(Camera, ScaledFollowsPixelCentreConvention) {
  const Camera camera = TestCamera(-0.1, 0.02);
  const Camera half = camera.Scaled(0.5);
  EXPECT_EQ(half.width, 320);
  EXPECT_EQ(half.height, 240);
  EXPECT_EQ(half.focal, 250.0);
  EXPECT_EQ(half.cx, (322.25 + 0.5) * 0.5 - 0.5);
  EXPECT_EQ(half.cy, (236.75 + 0.5) * 0.5 - 0.5);
  EXPECT_EQ(half.k1, -0.1);
  EXPECT_EQ(half.k2, 0.02);

  // The image centre stays the image centre.
  const Camera centred = Camera::FromFocal(640, 480, 500.0).Scaled(2.0);
  EXPECT_EQ(centred.cx, (1280 - 1) / 2.0);
  EXPECT_EQ(centred.cy, (960 - 1) / 2.0);

  // A 3-D point lands on the same continuous image position: pixel' + 0.5 = (pixel + 0.5) s.
  for (const double scale : {0.25, 0.5, 1.5, 3.0}) {
    const Camera scaled = camera.Scaled(scale);
    const Eigen::Vector3d point(0.7, -0.4, 3.0);
    const Eigen::Vector2d pixel = *camera.ImgFromCam(point);
    const Eigen::Vector2d scaled_pixel = *scaled.ImgFromCam(point);
    EXPECT_LT((scaled_pixel - ((pixel.array() + 0.5) * scale - 0.5).matrix()).norm(), 1e-9);
  }
}

TEST(Camera, ScaledRoundsImageSize) {
  const Camera camera = Camera::FromFocal(1001, 751, 800.0);
  const Camera half = camera.Scaled(0.5);
  EXPECT_EQ(half.width, 501);
  EXPECT_EQ(half.height, 376);
}

TEST(Camera, CheckAcceptsValidCamera) {
  std::string error = "untouched";
  EXPECT_TRUE(TestCamera(-0.2, 0.1).Check(&error));
  EXPECT_EQ(error, "untouched");
  EXPECT_TRUE(TestCamera(0.0, 0.0).Check(nullptr));
}

TEST(Camera, CheckRejectsInvalidCameraWithMessage) {
  struct Case {
    Camera camera;
    std::string expected_substring;
  };
  Camera zero_width = TestCamera(0, 0);
  zero_width.width = 0;
  Camera negative_height = TestCamera(0, 0);
  negative_height.height = -5;
  Camera zero_focal = TestCamera(0, 0);
  zero_focal.focal = 0.0;
  Camera negative_focal = TestCamera(0, 0);
  negative_focal.focal = -100.0;
  Camera infinite_focal = TestCamera(0, 0);
  infinite_focal.focal = INFINITY;
  Camera nan_cx = TestCamera(0, 0);
  nan_cx.cx = std::nan("");
  Camera nan_k2 = TestCamera(0, 0);
  nan_k2.k2 = std::nan("");
  const std::vector<Case> cases = {
      {zero_width, "image size must be positive, got 0x480"},
      {negative_height, "image size must be positive, got 640x-5"},
      {zero_focal, "focal length must be positive and finite, got 0"},
      {negative_focal, "focal length must be positive and finite, got -100"},
      {infinite_focal, "focal length must be positive and finite"},
      {nan_cx, "principal point and distortion must be finite"},
      {nan_k2, "principal point and distortion must be finite"},
  };
  for (const Case& c : cases) {
    std::string error;
    EXPECT_FALSE(c.camera.Check(&error)) << c.camera;
    EXPECT_NE(error.find(c.expected_substring), std::string::npos) << error;
    EXPECT_FALSE(c.camera.Check(nullptr));
  }
}

TEST(Camera, StreamsAllFields) {
  std::ostringstream os;
  os << TestCamera(-0.25, 0.5);
  EXPECT_EQ(os.str(), "Camera(640x480, f=500, c=(322.25, 236.75), k1=-0.25, k2=0.5)");
}

}  // namespace
}  // namespace reconduit
