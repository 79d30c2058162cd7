#include "core/mvs/mvs_view.h"

#include "core/scene/render.h"
#include "core/scene/textured_scene.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace reconduit {
namespace {

TexturedScene Wall() {
  TexturedScene scene;
  TexturedQuad wall;
  wall.origin = Eigen::Vector3d(-10, -10, 0);
  wall.edge_u = Eigen::Vector3d(20, 0, 0);
  wall.edge_v = Eigen::Vector3d(0, 20, 0);
  wall.texture.cell_size = 0.8;  // Shapes of 4-60 px in the 200-px working view.
  scene.quads.push_back(wall);
  return scene;
}

TEST(PrepareView, RemovesTheDistortionAndScalesToTheWorkingSize) {
  Camera camera = Camera::FromFocal(400, 300, 320.0);
  camera.cx = 203.0;
  camera.cy = 147.5;
  camera.k1 = 0.12;  // Pincushion: the undistorted view's corners lie outside the photo.
  camera.k2 = 0.02;
  const Rigid3d pose = Rigid3d::LookAt({0.3, -0.2, 4.0}, {0, 0, 0}, Eigen::Vector3d::UnitY());
  RenderOptions render;
  render.samples_per_axis = 4;
  const cv::Mat photo = RenderScene(Wall(), camera, pose, render).image;

  const PreparedView prepared = PrepareView(photo, camera, pose, 200);
  const Camera& working = prepared.view.camera;
  EXPECT_EQ(working.width, 200);
  EXPECT_EQ(working.height, 150);
  EXPECT_DOUBLE_EQ(working.focal, 160.0);
  EXPECT_DOUBLE_EQ(working.cx, (203.0 + 0.5) * 0.5 - 0.5);
  EXPECT_EQ(working.k1, 0.0);
  EXPECT_EQ(working.k2, 0.0);
  ASSERT_EQ(prepared.view.gray.type(), CV_32FC1);
  ASSERT_EQ(prepared.view.gray.size(), cv::Size(200, 150));
  ASSERT_EQ(prepared.color.size(), cv::Size(200, 150));

  // What a pinhole camera of the working size sees, and the photo only scaled, distortion left
  // in. Grey levels differ after any resampling (bilinear interpolation blurs edges at
  // fractional positions), so the test measures where the pixels go: the sub-pixel shift
  // between blocks of the prepared view and of the truth (phase correlation), near the centre
  // and towards the corners, where pincushion distortion moves pixels the most.
  const cv::Mat truth = RenderScene(Wall(), working, pose, render).image;
  cv::Mat naive;
  cv::resize(photo, naive, cv::Size(200, 150), 0, 0, cv::INTER_AREA);
  auto shift = [&](const cv::Mat& image, const cv::Rect& block) {
    cv::Mat a, b;
    cv::cvtColor(image(block), a, cv::COLOR_BGR2GRAY);
    cv::cvtColor(truth(block), b, cv::COLOR_BGR2GRAY);
    a.convertTo(a, CV_64F);
    b.convertTo(b, CV_64F);
    const cv::Point2d d = cv::phaseCorrelate(a, b);
    return std::hypot(d.x, d.y);
  };
  for (const cv::Rect& block :
       {cv::Rect(76, 51, 48, 48), cv::Rect(22, 18, 48, 48), cv::Rect(130, 18, 48, 48),
        cv::Rect(22, 84, 48, 48), cv::Rect(130, 84, 48, 48)}) {
    const double prepared_shift = shift(prepared.color, block);
    const double naive_shift = shift(naive, block);
    LOG_INFO << "block at (" << block.x << ", " << block.y << "): shift " << prepared_shift
             << " px undistorted, " << naive_shift << " px only scaled";
    EXPECT_LT(prepared_shift, 0.15);
    if (block.x != 76) {
      EXPECT_GT(naive_shift, 1.0);
    }
  }
  EXPECT_EQ(prepared.valid.at<std::uint8_t>(0, 0), 0);
  EXPECT_EQ(prepared.valid.at<std::uint8_t>(75, 100), 255);
}

TEST(PrepareView, KeepsASmallPhotoAtItsSize) {
  const Camera camera = Camera::FromFocal(120, 90, 100.0);
  const cv::Mat photo(90, 120, CV_8UC3, cv::Scalar(10, 20, 30));
  const PreparedView prepared = PrepareView(photo, camera, Rigid3d(), 1600);
  EXPECT_EQ(prepared.view.camera.width, 120);
  EXPECT_EQ(prepared.view.camera.focal, 100.0);
  EXPECT_EQ(prepared.color.at<cv::Vec3b>(45, 60), cv::Vec3b(10, 20, 30));
  EXPECT_THROW(PrepareView(photo, Camera::FromFocal(100, 90, 100.0), Rigid3d(), 0), CheckError);
}

}  // namespace
}  // namespace reconduit
