#include "core/scene/render.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <optional>
#include <string>

namespace reconduit {
namespace {

// A 3 m x 2 m wall in the plane y = 0 (x in [-1.5, 1.5], z in [0, 2]); u along +x, v up.
TexturedScene WallScene() {
  TexturedScene scene;
  TexturedQuad wall;
  wall.origin = {-1.5, 0.0, 0.0};
  wall.edge_u = {3.0, 0.0, 0.0};
  wall.edge_v = {0.0, 0.0, 2.0};
  wall.texture.seed = 11;
  wall.texture.base_color = {90.0, 150.0, 200.0};
  scene.quads.push_back(wall);
  scene.background_color = {10.0, 200.0, 30.0};
  return scene;
}

// A distorted camera 4 m in front of the wall, looking at it obliquely, so that the wall
// fills part of the image and the rest is background.
Camera WallCamera() {
  Camera camera = Camera::FromFocal(320, 240, 260.0);
  camera.cx = 161.3;
  camera.cy = 118.2;
  camera.k1 = -0.15;
  camera.k2 = 0.03;
  return camera;
}
Rigid3d WallPose() {
  return Rigid3d::LookAt({1.2, -4.0, 1.8}, {0.2, 0.0, 0.9}, Eigen::Vector3d::UnitZ());
}

// Where the ray through `pixel` meets the plane y = 0, as wall coordinates (u, v), and its
// depth; computed here independently of the renderer.
struct PlaneHit {
  Eigen::Vector2d uv;
  double depth;
};
std::optional<PlaneHit> HitWallPlane(const Camera& camera,
                                     const Rigid3d& cam_from_world,
                                     const Eigen::Vector2d& pixel) {
  const auto ray_in_cam = camera.CamFromImg(pixel);
  if (!ray_in_cam) return std::nullopt;
  const Eigen::Vector3d center = cam_from_world.CenterInWorld();
  const Eigen::Vector3d direction = cam_from_world.rotation.inverse() * *ray_in_cam;
  const double t = -center.y() / direction.y();
  if (!(t > 0.0)) return std::nullopt;
  const Eigen::Vector3d point = center + t * direction;
  return PlaneHit{{point.x() + 1.5, point.z()}, t};
}

bool InsideWall(const Eigen::Vector2d& uv, double margin) {
  return uv.x() > margin && uv.x() < 3.0 - margin && uv.y() > margin && uv.y() < 2.0 - margin;
}

Eigen::Vector3d PixelColor(const cv::Mat& image, int row, int col) {
  const cv::Vec3b bgr = image.at<cv::Vec3b>(row, col);
  return {static_cast<double>(bgr[0]), static_cast<double>(bgr[1]), static_cast<double>(bgr[2])};
}

TEST(RenderOptions, DefaultsAreValidAndBadSamplesRejected) {
  std::string error;
  EXPECT_TRUE(RenderOptions().Check(&error)) << error;
  RenderOptions options;
  options.samples_per_axis = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("samples_per_axis"), std::string::npos) << error;
  options.samples_per_axis = 9;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THROW(RenderScene(WallScene(), WallCamera(), WallPose(), options), CheckError);
}

TEST(RenderScene, RejectsInvalidCameraAndScene) {
  Camera camera = WallCamera();
  camera.focal = 0.0;
  EXPECT_THROW(RenderScene(WallScene(), camera, WallPose()), CheckError);
  TexturedScene scene = WallScene();
  scene.quads[0].edge_v = 2.0 * scene.quads[0].edge_u;  // Degenerate quad.
  EXPECT_THROW(RenderScene(scene, WallCamera(), WallPose()), CheckError);
}

TEST(RenderScene, ImageAndDepthHaveCameraSizeAndType) {
  RenderOptions options;
  const RenderedView color = RenderScene(WallScene(), WallCamera(), WallPose(), options);
  EXPECT_EQ(color.image.rows, 240);
  EXPECT_EQ(color.image.cols, 320);
  EXPECT_EQ(color.image.type(), CV_8UC3);
  EXPECT_EQ(color.depth.rows, 240);
  EXPECT_EQ(color.depth.cols, 320);
  EXPECT_EQ(color.depth.type(), CV_32FC1);
  options.grayscale = true;
  EXPECT_EQ(RenderScene(WallScene(), WallCamera(), WallPose(), options).image.type(), CV_8UC1);
}

TEST(RenderScene, KnownSurfacePointsShowTheirTextureAndDepth) {
  const TexturedScene scene = WallScene();
  const Camera camera = WallCamera();
  const Rigid3d cam_from_world = WallPose();
  RenderOptions options;
  options.samples_per_axis = 1;  // One ray through each pixel centre: exact comparison.
  const RenderedView view = RenderScene(scene, camera, cam_from_world, options);

  int num_checked = 0;
  for (double u = 0.05; u < 3.0; u += 0.1) {
    for (double v = 0.05; v < 2.0; v += 0.1) {
      // A known point on the wall, projected with the (distorted) camera model.
      const Eigen::Vector3d point = scene.quads[0].PointAt(u, v);
      const auto projection = camera.ImgFromCam(cam_from_world * point);
      ASSERT_TRUE(projection.has_value());
      const int col = static_cast<int>(std::lround(projection->x()));
      const int row = static_cast<int>(std::lround(projection->y()));
      if (col < 0 || row < 0 || col >= camera.width || row >= camera.height) continue;
      // The pixel centre's ray meets the wall within a pixel's footprint (< 2.5 cm here) of
      // the point...
      const auto hit = HitWallPlane(camera, cam_from_world, Eigen::Vector2d(col, row));
      ASSERT_TRUE(hit.has_value());
      EXPECT_LT((hit->uv - Eigen::Vector2d(u, v)).norm(), 0.025);
      // ...and the pixel shows the texture there, at that depth.
      const Eigen::Vector3d expected =
          EvaluateTexture(scene.quads[0].texture, hit->uv.x(), hit->uv.y());
      EXPECT_LE((PixelColor(view.image, row, col) - expected).cwiseAbs().maxCoeff(), 0.5 + 1e-6)
          << "at u=" << u << " v=" << v;
      EXPECT_NEAR(view.depth.at<float>(row, col), hit->depth, 1e-5 * hit->depth);
      ++num_checked;
    }
  }
  // Most of the 30 x 20 grid is in view.
  EXPECT_GT(num_checked, 300);
}

TEST(RenderScene, SupersampledPixelsMatchSmoothTexture) {
  const TexturedScene scene = WallScene();
  const Camera camera = WallCamera();
  const Rigid3d cam_from_world = WallPose();
  RenderOptions options;
  options.samples_per_axis = 3;
  const RenderedView view = RenderScene(scene, camera, cam_from_world, options);

  // Where the texture is nearly constant over a pixel's footprint, the box-filtered pixel
  // equals the texture at the centre; where it is not, the pixel lies within the range of
  // texture values over the footprint.
  int num_smooth = 0, num_checked = 0;
  for (int row = 2; row < camera.height; row += 3) {
    for (int col = 2; col < camera.width; col += 3) {
      const auto center = HitWallPlane(camera, cam_from_world, Eigen::Vector2d(col, row));
      if (!center || !InsideWall(center->uv, 0.05)) continue;
      const ProceduralTexture& texture = scene.quads[0].texture;
      const Eigen::Vector3d expected = EvaluateTexture(texture, center->uv.x(), center->uv.y());
      Eigen::Vector3d low = expected, high = expected;
      // A 7 x 7 grid over the footprint that includes the renderer's 3 x 3 sample positions.
      for (int k = 0; k <= 6; ++k) {
        for (int l = 0; l <= 6; ++l) {
          const double dx = k / 6.0 - 0.5, dy = l / 6.0 - 0.5;
          const auto hit =
              HitWallPlane(camera, cam_from_world, Eigen::Vector2d(col + dx, row + dy));
          const Eigen::Vector3d color = EvaluateTexture(texture, hit->uv.x(), hit->uv.y());
          low = low.cwiseMin(color);
          high = high.cwiseMax(color);
        }
      }
      const Eigen::Vector3d pixel = PixelColor(view.image, row, col);
      EXPECT_TRUE((pixel.array() >= low.array() - 1.0).all() &&
                  (pixel.array() <= high.array() + 1.0).all())
          << "pixel " << pixel.transpose() << " outside [" << low.transpose() << "], ["
          << high.transpose() << "]";
      if ((high - low).maxCoeff() < 4.0) {
        ++num_smooth;
        EXPECT_LE((pixel - expected).cwiseAbs().maxCoeff(), 3.0);
      }
      ++num_checked;
    }
  }
  EXPECT_GT(num_checked, 1500);
  EXPECT_GT(num_smooth, 100);
}

TEST(RenderScene, RaysThatMissShowBackgroundAndZeroDepth) {
  const TexturedScene scene = WallScene();
  const Camera camera = WallCamera();
  const Rigid3d cam_from_world = WallPose();
  const RenderedView view = RenderScene(scene, camera, cam_from_world);
  int num_background = 0, num_wall = 0;
  for (int row = 0; row < camera.height; ++row) {
    for (int col = 0; col < camera.width; ++col) {
      const auto hit = HitWallPlane(camera, cam_from_world, Eigen::Vector2d(col, row));
      // Margins of ~2 pixel footprints keep the antialiased wall border out of both sets.
      if (!hit || !InsideWall(hit->uv, -0.05)) {
        ++num_background;
        EXPECT_EQ(PixelColor(view.image, row, col), scene.background_color);
        EXPECT_EQ(view.depth.at<float>(row, col), 0.0f);
      } else if (InsideWall(hit->uv, 0.05)) {
        ++num_wall;
        EXPECT_GT(view.depth.at<float>(row, col), 3.0f);
      }
    }
  }
  EXPECT_GT(num_background, 5000);
  EXPECT_GT(num_wall, 5000);
}

TEST(RenderScene, NearerSurfaceOccludes) {
  TexturedScene scene = WallScene();
  TexturedQuad panel;  // 0.6 m square 1 m in front of the wall.
  panel.origin = {-0.1, -1.0, 0.6};
  panel.edge_u = {0.6, 0.0, 0.0};
  panel.edge_v = {0.0, 0.0, 0.6};
  panel.texture.seed = 99;
  scene.quads.push_back(panel);
  const Camera camera = WallCamera();
  const Rigid3d cam_from_world = WallPose();
  RenderOptions options;
  options.samples_per_axis = 1;
  const RenderedView view = RenderScene(scene, camera, cam_from_world, options);

  const Eigen::Vector3d point = panel.PointAt(0.3, 0.3);
  const Eigen::Vector2d pixel = *camera.ImgFromCam(cam_from_world * point);
  const int col = static_cast<int>(std::lround(pixel.x()));
  const int row = static_cast<int>(std::lround(pixel.y()));
  EXPECT_NEAR(view.depth.at<float>(row, col), (cam_from_world * point).z(), 0.02);
  const auto wall_hit = HitWallPlane(camera, cam_from_world, Eigen::Vector2d(col, row));
  EXPECT_GT(wall_hit->depth, view.depth.at<float>(row, col) + 0.5);
  // The ray through the pixel hits the panel; IntersectRay agrees with the renderer.
  const Eigen::Vector3d direction =
      cam_from_world.rotation.inverse() * *camera.CamFromImg(Eigen::Vector2d(col, row));
  const auto hit = IntersectRay(scene, cam_from_world.CenterInWorld(), direction);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, 1);
  EXPECT_NEAR(hit->distance, view.depth.at<float>(row, col), 1e-5);
  EXPECT_LT((hit->uv - Eigen::Vector2d(0.3, 0.3)).norm(), 0.02);
  const Eigen::Vector3d expected = EvaluateTexture(panel.texture, hit->uv.x(), hit->uv.y());
  EXPECT_LE((PixelColor(view.image, row, col) - expected).cwiseAbs().maxCoeff(), 0.5 + 1e-6);
}

TEST(RenderScene, DeterministicAndIndependentOfThreads) {
  const TexturedScene scene = MakeBoxRoomScene(3);
  const Camera camera = Camera::FromFocal(200, 150, 160.0);
  const Rigid3d cam_from_world = BoxRoomCameraRing(4)[1];
  RenderOptions options;
  options.num_threads = 1;
  const RenderedView a = RenderScene(scene, camera, cam_from_world, options);
  options.num_threads = 2;
  const RenderedView b = RenderScene(scene, camera, cam_from_world, options);
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
  // A different room is a different picture.
  const RenderedView c = RenderScene(MakeBoxRoomScene(4), camera, cam_from_world, options);
  EXPECT_GT(cv::norm(a.image, c.image, cv::NORM_L1) / a.image.total(), 20.0);
}

TEST(RenderScene, GrayscaleMatchesColourConversion) {
  const TexturedScene scene = WallScene();
  RenderOptions options;
  const RenderedView color = RenderScene(scene, WallCamera(), WallPose(), options);
  options.grayscale = true;
  const RenderedView gray = RenderScene(scene, WallCamera(), WallPose(), options);
  cv::Mat converted;
  cv::cvtColor(color.image, converted, cv::COLOR_BGR2GRAY);
  // Gray is computed before rounding to 8 bits, cvtColor after: at most 1 level apart.
  EXPECT_LE(cv::norm(gray.image, converted, cv::NORM_INF), 1.0);
  EXPECT_EQ(cv::norm(gray.depth, color.depth, cv::NORM_INF), 0.0);
}

TEST(MakeBoxRoomScene, RingViewsSeeTheRoomEverywhere) {
  const TexturedScene scene = MakeBoxRoomScene();
  std::string error;
  ASSERT_TRUE(scene.Check(&error)) << error;
  EXPECT_EQ(scene.quads.size(), 5u + 4u * 5u);
  const Camera camera = Camera::FromFocal(160, 120, 125.0);
  RenderOptions options;
  options.samples_per_axis = 1;
  for (const Rigid3d& cam_from_world : BoxRoomCameraRing(6)) {
    const RenderedView view = RenderScene(scene, camera, cam_from_world, options);
    double min_depth = 1e9, max_depth = 0.0;
    cv::minMaxLoc(view.depth, &min_depth, &max_depth);
    // The room is closed below the walls' top: every pixel hits something, from the boxes
    // (~2-3 m) to the far walls (the farthest corner is 3.5 + 6 sqrt(2) < 12 m away).
    EXPECT_GT(min_depth, 0.5);
    EXPECT_LT(min_depth, 3.5);
    EXPECT_GT(max_depth, 6.0);
    EXPECT_LT(max_depth, 12.0);
  }
}

TEST(RenderScene, TerrainPixelsLieOnTheSurfaceWithItsTexture) {
  const TexturedScene scene = MakeTerrainScene(7);
  const TexturedHeightField& field = scene.height_fields[0];
  // Odd sizes put the principal point on a pixel centre, (80, 60): the camera looks at a known
  // surface point obliquely, so that pixel's depth is that point's.
  const Camera camera = Camera::FromFocal(161, 121, 150.0);
  const Eigen::Vector3d target(1.0, -2.0, field.Height(1.0, -2.0));
  const Rigid3d cam_from_world =
      Rigid3d::LookAt(target + Eigen::Vector3d(-4.0, -6.0, 7.0), target, Eigen::Vector3d::UnitZ());
  RenderOptions options;
  options.samples_per_axis = 1;
  const RenderedView view = RenderScene(scene, camera, cam_from_world, options);
  EXPECT_NEAR(view.depth.at<float>(60, 80), (cam_from_world * target).z(), 2e-6 * 10.0);

  // Every pixel centre's hit is on the surface (to float precision of the depth), shows the
  // texture there, and the SceneRayCaster agrees.
  const Eigen::Vector3d center = cam_from_world.CenterInWorld();
  const SceneRayCaster caster(scene);
  int num_surface = 0;
  for (int row = 0; row < camera.height; row += 4) {
    for (int col = 0; col < camera.width; col += 4) {
      const Eigen::Vector3d direction =
          cam_from_world.rotation.inverse() * *camera.CamFromImg(Eigen::Vector2d(col, row));
      const auto hit = caster.Intersect(center, direction);
      const float depth = view.depth.at<float>(row, col);
      if (!hit) {
        EXPECT_EQ(depth, 0.0f);
        continue;
      }
      ++num_surface;
      EXPECT_NEAR(depth, hit->distance, 1e-6 * hit->distance);
      const Eigen::Vector3d point = center + static_cast<double>(depth) * direction;
      EXPECT_NEAR(point.z(), field.Height(point.x(), point.y()), 2e-5);
      const Eigen::Vector3d expected = EvaluateTexture(field.texture, hit->uv.x(), hit->uv.y());
      EXPECT_LE((PixelColor(view.image, row, col) - expected).cwiseAbs().maxCoeff(), 0.5 + 1e-6);
    }
  }
  EXPECT_GT(num_surface, 1000);
}

TEST(RenderScene, AerialGridSeesOnlyTerrain) {
  const TexturedScene scene = MakeTerrainScene();
  const Camera camera = Camera::FromFocal(160, 120, 150.0);
  RenderOptions options;
  options.samples_per_axis = 1;
  for (const Rigid3d& cam_from_world : TerrainCameraGrid(3, 3, 3.0, 12.0)) {
    const RenderedView view = RenderScene(scene, camera, cam_from_world, options);
    double min_depth = 0.0, max_depth = 0.0;
    cv::minMaxLoc(view.depth, &min_depth, &max_depth);
    // 12 m up over relief of a few metres; the footprint (13 x 10 m) stays inside the terrain.
    EXPECT_GT(min_depth, 8.0);
    EXPECT_LT(max_depth, 14.0);
  }
}

}  // namespace
}  // namespace reconduit
