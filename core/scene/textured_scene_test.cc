#include "core/scene/textured_scene.h"

#include <gtest/gtest.h>

#include <string>

namespace reconduit {
namespace {

// Two unit-ish quads facing the z axis: one at z = 2 (u along x, v along y), one at z = 5.
TexturedScene TwoQuads() {
  TexturedScene scene;
  TexturedQuad near;
  near.origin = {-1.0, -0.5, 2.0};
  near.edge_u = {2.0, 0.0, 0.0};
  near.edge_v = {0.0, 1.0, 0.0};
  TexturedQuad far = near;
  far.origin = {-3.0, -3.0, 5.0};
  far.edge_u = {6.0, 0.0, 0.0};
  far.edge_v = {0.0, 6.0, 0.0};
  scene.quads = {near, far};
  return scene;
}

TEST(TexturedScene, CheckAcceptsValidScenes) {
  std::string error;
  EXPECT_TRUE(TwoQuads().Check(&error)) << error;
  EXPECT_TRUE(TexturedScene().Check(&error)) << error;
  EXPECT_TRUE(MakeBoxRoomScene(5).Check(&error)) << error;
}

TEST(TexturedScene, CheckRejectsBadScenesWithMessage) {
  std::string error;
  TexturedScene scene = TwoQuads();
  scene.quads[1].edge_v = Eigen::Vector3d::Zero();
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "quad 1: edges are zero or parallel");
  scene = TwoQuads();
  scene.quads[0].edge_v = -3.0 * scene.quads[0].edge_u;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "quad 0: edges are zero or parallel");
  scene = TwoQuads();
  scene.quads[0].origin.x() = NAN;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "quad 0: non-finite geometry");
  scene = TwoQuads();
  scene.quads[1].texture.cell_size = -1.0;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_NE(error.find("quad 1: texture: cell_size"), std::string::npos) << error;
  scene = TwoQuads();
  scene.background_color.z() = 300.0;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_NE(error.find("background_color"), std::string::npos) << error;
}

TEST(TexturedQuad, PointAtUsesMetricCoordinates) {
  const TexturedQuad quad = TwoQuads().quads[1];
  EXPECT_EQ(quad.PointAt(0.0, 0.0), quad.origin);
  EXPECT_LT((quad.PointAt(6.0, 6.0) - Eigen::Vector3d(3.0, 3.0, 5.0)).norm(), 1e-12);
  EXPECT_LT((quad.PointAt(1.5, 2.0) - Eigen::Vector3d(-1.5, -1.0, 5.0)).norm(), 1e-12);
}

TEST(IntersectRay, FindsNearestHitWithSurfaceCoordinates) {
  const TexturedScene scene = TwoQuads();
  // Through the near quad.
  auto hit = IntersectRay(scene, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.25, 0.1, 1.0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, 0);
  EXPECT_NEAR(hit->distance, 2.0, 1e-12);
  EXPECT_LT((hit->point - Eigen::Vector3d(0.5, 0.2, 2.0)).norm(), 1e-12);
  EXPECT_LT((hit->uv - Eigen::Vector2d(1.5, 0.7)).norm(), 1e-12);
  // Past the near quad's edge, onto the far one; the direction's length scales distance.
  hit = IntersectRay(scene, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.6, 2.0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, 1);
  EXPECT_NEAR(hit->distance, 2.5, 1e-12);
  EXPECT_LT((hit->uv - Eigen::Vector2d(3.0, 4.5)).norm(), 1e-12);
  // From behind (quads are two-sided), the far quad is hit first.
  hit = IntersectRay(scene, Eigen::Vector3d(0.0, 0.0, 9.0), Eigen::Vector3d(0.0, 0.0, -1.0));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, 1);
  EXPECT_NEAR(hit->distance, 4.0, 1e-12);
}

TEST(IntersectRay, MissesBehindParallelAndOutside) {
  const TexturedScene scene = TwoQuads();
  EXPECT_FALSE(IntersectRay(scene, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -1)));
  EXPECT_FALSE(IntersectRay(scene, Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 0)));
  EXPECT_FALSE(IntersectRay(scene, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.7, 0.0, 1.0)));
  EXPECT_FALSE(IntersectRay(TexturedScene(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1)));
}

TEST(MakeBoxRoomScene, DeterministicFromSeed) {
  const TexturedScene a = MakeBoxRoomScene(1), b = MakeBoxRoomScene(1), c = MakeBoxRoomScene(2);
  ASSERT_EQ(a.quads.size(), b.quads.size());
  for (std::size_t i = 0; i < a.quads.size(); ++i) {
    EXPECT_EQ(a.quads[i].origin, b.quads[i].origin);
    EXPECT_EQ(a.quads[i].texture.seed, b.quads[i].texture.seed);
  }
  EXPECT_NE(a.quads.back().origin, c.quads.back().origin);
  // Every surface has its own texture.
  for (std::size_t i = 1; i < a.quads.size(); ++i) {
    EXPECT_NE(a.quads[i].texture.seed, a.quads[0].texture.seed);
  }
}

TEST(BoxRoomCameraRing, CamerasInsideTheRoomAroundTheBoxes) {
  const std::vector<Rigid3d> poses = BoxRoomCameraRing(5, 180.0);
  ASSERT_EQ(poses.size(), 5u);
  for (const Rigid3d& pose : poses) {
    const Eigen::Vector3d center = pose.CenterInWorld();
    EXPECT_NEAR(center.head<2>().norm(), 3.5, 1e-12);
    EXPECT_NEAR(center.z(), 1.6, 1e-12);
    EXPECT_LT((pose * Eigen::Vector3d(0.0, 0.0, 0.4)).head<2>().norm(), 1e-12);
  }
}

}  // namespace
}  // namespace reconduit
