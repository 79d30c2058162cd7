#include "core/mvs/fusion.h"

#include "core/scene/render.h"
#include "core/scene/textured_scene.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>

namespace reconduit {
namespace {

// Exact depth maps of the floor z = 0 (normals (0, 0, 1) in the world) seen from above.
struct Views {
  std::vector<DepthMap> maps;
  std::vector<FusionView> fusion;
};

int MaxOf(const cv::Mat& quality) {
  double max = 0.0;
  cv::minMaxLoc(quality, nullptr, &max);
  return static_cast<int>(max);
}

Views FloorViews(const std::vector<Eigen::Vector3d>& centers, int width = 80, int height = 60) {
  TexturedScene scene;
  TexturedQuad floor;
  floor.origin = Eigen::Vector3d(-10, -10, 0);
  floor.edge_u = Eigen::Vector3d(20, 0, 0);
  floor.edge_v = Eigen::Vector3d(0, 20, 0);
  scene.quads.push_back(floor);
  Views views;
  views.maps.resize(centers.size());
  for (std::size_t i = 0; i < centers.size(); ++i) {
    FusionView view;
    view.camera = Camera::FromFocal(width, height, 60.0);
    view.cam_from_world = Rigid3d::LookAt(
        centers[i], Eigen::Vector3d(centers[i].x(), centers[i].y(), 0), Eigen::Vector3d::UnitY());
    RenderOptions options;
    options.samples_per_axis = 1;
    const RenderedView rendered = RenderScene(scene, view.camera, view.cam_from_world, options);
    DepthMap& map = views.maps[i];
    map.depth = rendered.depth.clone();
    const Eigen::Vector3f n =
        (view.cam_from_world.rotation * Eigen::Vector3d::UnitZ()).cast<float>();
    map.normal = cv::Mat(height, width, CV_32FC3, cv::Scalar(n.x(), n.y(), n.z()));
    map.cost = cv::Mat(height, width, CV_32FC1, cv::Scalar(0.1));
    view.color = rendered.image;
    view.image_id = 100 + static_cast<int>(i);
    views.fusion.push_back(view);
  }
  for (std::size_t i = 0; i < centers.size(); ++i) views.fusion[i].map = &views.maps[i];
  return views;
}

TEST(Fusion, PointsOnTheSurfaceOncePerSurfaceSample) {
  // Three views 5 m above the floor, 1 m apart: each sees a 6.7 x 5 m patch.
  Views views = FloorViews({{0, 0, 5}, {1, 0, 5}, {2, 0, 5}});
  const FusionResult result = FuseDepthMaps(views.fusion, FusionOptions());
  const DenseCloud& cloud = result.cloud;
  ASSERT_GT(cloud.size(), 0u);
  ASSERT_EQ(cloud.visibility_offsets.size(), cloud.size() + 1);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    EXPECT_NEAR(cloud.positions[i].z(), 0.0f, 1e-4f);
    EXPECT_GT(cloud.normals[i].z(), 0.999f);
    const std::uint32_t begin = cloud.visibility_offsets[i], end = cloud.visibility_offsets[i + 1];
    ASSERT_GE(end - begin, 2u);  // Two views at least confirm every point.
    for (std::uint32_t k = begin; k + 1 < end; ++k)
      EXPECT_LT(cloud.visibility[k], cloud.visibility[k + 1]);
  }
  // Duplicates are merged: fewer points than confirmed pixels, at least as many as one view
  // has pixels seen by another view (4800 pixels per view; views overlap by 85 % and 70 %).
  int confirmed_pixels = 0;
  for (const cv::Mat& q : result.quality) {
    for (int y = 0; y < q.rows; ++y)
      for (int x = 0; x < q.cols; ++x) confirmed_pixels += q.at<std::uint8_t>(y, x) >= 2;
  }
  EXPECT_LT(static_cast<int>(cloud.size()), confirmed_pixels);
  EXPECT_GT(cloud.size(), 4000u);
  // Quality: the middle view's centre is seen by all three; the left view's left edge by
  // nobody else.
  EXPECT_EQ(result.quality[1].at<std::uint8_t>(30, 40), 3);
  EXPECT_EQ(result.quality[0].at<std::uint8_t>(30, 1), 1);
  // Exact maps agree everywhere they overlap.
  ASSERT_EQ(result.neighbor_agreement.size(), 3u);
  for (double agreement : result.neighbor_agreement) EXPECT_DOUBLE_EQ(agreement, 1.0);
}

TEST(Fusion, NeighbourAgreementIsTheShareWithinOnePercent) {
  // Two views over the same floor; a quarter of view 1's pixels 3 % too far (wrong), another
  // quarter 0.5 % too far (within 1 %).
  Views views = FloorViews({{0, 0, 5}, {0.2, 0, 5}});
  views.maps[1].depth(cv::Rect(0, 0, 40, 30)) *= 1.03;
  views.maps[1].depth(cv::Rect(40, 0, 40, 30)) *= 1.005;
  const FusionResult result = FuseDepthMaps(views.fusion, FusionOptions());
  EXPECT_NEAR(result.neighbor_agreement[1], 0.75, 0.03);
  EXPECT_NEAR(result.neighbor_agreement[0], 0.75, 0.03);
  // No overlap: NaN.
  Views apart = FloorViews({{0, 0, 5}, {100, 0, 5}});
  EXPECT_TRUE(std::isnan(FuseDepthMaps(apart.fusion, FusionOptions()).neighbor_agreement[0]));
}

TEST(Fusion, AWrongDepthIsNotConfirmedAndNotFused) {
  Views views = FloorViews({{0, 0, 5}, {0.5, 0, 5}, {1, 0, 5}});
  // View 1 gets its centre 3 % too far: no other view agrees there.
  views.maps[1].depth(cv::Rect(30, 20, 20, 20)) *= 1.03;
  const FusionResult result = FuseDepthMaps(views.fusion, FusionOptions());
  EXPECT_EQ(result.quality[1].at<std::uint8_t>(30, 40), 1);
  EXPECT_EQ(result.quality[1].at<std::uint8_t>(5, 40), 3);
  ASSERT_GT(result.cloud.size(), 1000u);
  for (std::size_t i = 0; i < result.cloud.size(); ++i)
    EXPECT_NEAR(result.cloud.positions[i].z(), 0.0f, 1e-4f) << i;
  // A tilted normal is not confirmed either.
  views = FloorViews({{0, 0, 5}, {0.5, 0, 5}});
  views.maps[1].normal.setTo(cv::Scalar(0.0, std::sin(0.3), -std::cos(0.3)));  // 17 deg off.
  EXPECT_EQ(FuseDepthMaps(views.fusion, FusionOptions()).cloud.size(), 0u);
}

TEST(Fusion, NeighboursLimitTheChecksAndMinViewsTheOutput) {
  Views views = FloorViews({{0, 0, 5}, {0.5, 0, 5}, {1, 0, 5}});
  FusionOptions options;
  options.min_views = 3;
  const FusionResult three = FuseDepthMaps(views.fusion, options);
  ASSERT_GT(three.cloud.size(), 1000u);
  for (std::size_t i = 0; i < three.cloud.size(); ++i) {
    EXPECT_EQ(three.cloud.visibility_offsets[i + 1] - three.cloud.visibility_offsets[i], 3u);
  }
  // Each view checked against one other only: no pixel can have more than two agreeing views.
  views.fusion[0].neighbors = {2};
  views.fusion[1].neighbors = {0};
  views.fusion[2].neighbors = {0};
  options.min_views = 2;
  const FusionResult limited = FuseDepthMaps(views.fusion, options);
  EXPECT_EQ(MaxOf(limited.quality[0]), 2);
  EXPECT_EQ(MaxOf(limited.quality[1]), 2);
}

TEST(Fusion, RejectsBadInput) {
  Views views = FloorViews({{0, 0, 5}, {0.5, 0, 5}});
  FusionOptions options;
  options.min_views = 1;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THROW(FuseDepthMaps(views.fusion, options), CheckError);
  views.fusion[0].neighbors = {5};
  EXPECT_THROW(FuseDepthMaps(views.fusion, FusionOptions()), CheckError);
  views.fusion[0].neighbors = {};
  views.fusion[1].map = nullptr;
  EXPECT_THROW(FuseDepthMaps(views.fusion, FusionOptions()), CheckError);
}

}  // namespace
}  // namespace reconduit
