#include "core/scene/textured_scene.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>

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

// Two hills and a hollow over [-5, 5]^2, base 0.5 m.
TexturedHeightField ThreeHills() {
  TexturedHeightField field;
  field.min_xy = {-5.0, -5.0};
  field.max_xy = {5.0, 5.0};
  field.base_z = 0.5;
  field.hills = {{{-1.5, 0.5}, 1.2, 3.5}, {{2.0, -1.0}, 0.8, 2.5}, {{0.5, 2.5}, -0.6, 3.0}};
  field.texture.seed = 4;
  return field;
}

TEST(TexturedHeightField, DerivativesMatchFiniteDifferences) {
  const TexturedHeightField field = ThreeHills();
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> coordinate(-5.0, 5.0);
  constexpr double h = 1e-5;
  for (int i = 0; i < 200; ++i) {
    const double x = coordinate(rng), y = coordinate(rng);
    Eigen::Vector2d g, gx, gy;
    Eigen::Matrix2d hessian;
    const double z = field.Evaluate(x, y, &g, &hessian);
    EXPECT_EQ(z, field.Height(x, y));
    EXPECT_NEAR(g.x(), (field.Height(x + h, y) - field.Height(x - h, y)) / (2 * h), 1e-8);
    EXPECT_NEAR(g.y(), (field.Height(x, y + h) - field.Height(x, y - h)) / (2 * h), 1e-8);
    field.Evaluate(x + h, y, &gx);
    field.Evaluate(x, y + h, &gy);
    EXPECT_LT((hessian.col(0) - (gx - g) / h).norm(), 1e-4);
    EXPECT_LT((hessian.col(1) - (gy - g) / h).norm(), 1e-4);
    EXPECT_LT((field.Normal(x, y) - Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized()).norm(),
              1e-15);
  }
  // Outside a hill's support it contributes nothing.
  EXPECT_EQ(field.Height(-4.9, -4.9), 0.5);
  // A single hill's steepest slope, at radius / sqrt(5) from its top.
  TexturedHeightField one;
  one.hills = {{{0.0, 0.0}, 2.0, 1.5}};
  Eigen::Vector2d g;
  one.Evaluate(1.5 / std::sqrt(5.0), 0.0, &g);
  EXPECT_NEAR(g.norm(), 1.7173 * 2.0 / 1.5, 1e-4);
}

TEST(TexturedHeightField, BoundsHoldEverywhereAndAreTight) {
  const TexturedHeightField field = ThreeHills();
  const HeightFieldBounds bounds = field.ComputeBounds();
  double min_z = 1e9, max_z = -1e9, max_slope = 0.0;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> coordinate(-5.0, 5.0);
  for (int i = 0; i < 200000; ++i) {
    Eigen::Vector2d g;
    const double z = field.Evaluate(coordinate(rng), coordinate(rng), &g);
    min_z = std::min(min_z, z);
    max_z = std::max(max_z, z);
    max_slope = std::max(max_slope, g.norm());
  }
  EXPECT_LE(bounds.min_height, min_z);
  EXPECT_GE(bounds.max_height, max_z);
  EXPECT_GE(bounds.max_slope, max_slope);
  EXPECT_GT(bounds.min_height, min_z - 0.05);
  EXPECT_LT(bounds.max_height, max_z + 0.05);
  EXPECT_LT(bounds.max_slope, max_slope + 0.05);
  // The top: the first hill, 1.2 m over the base (the hollow's support just reaches it).
  EXPECT_NEAR(max_z, 1.7, 0.01);
}

TEST(TexturedHeightField, CheckRejectsBadFields) {
  std::string error;
  TexturedScene scene;
  scene.height_fields.push_back(ThreeHills());
  EXPECT_TRUE(scene.Check(&error)) << error;
  scene.height_fields[0].hills[1].radius = 0.0;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "height field 0: hill radius <= 0");
  scene.height_fields[0] = ThreeHills();
  scene.height_fields[0].max_xy.y() = -6.0;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "height field 0: empty rectangle");
  scene.height_fields[0] = ThreeHills();
  scene.height_fields[0].hills[0].height = NAN;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_EQ(error, "height field 0: non-finite geometry");
  scene.height_fields[0] = ThreeHills();
  scene.height_fields[0].texture.num_layers = 99;
  EXPECT_FALSE(scene.Check(&error));
  EXPECT_NE(error.find("height field 0: texture: num_layers"), std::string::npos) << error;
}

// True when g(s) = ray height above the surface keeps one sign on (0, t) inside the rectangle,
// sampled finely.
bool NoCrossingBefore(const TexturedHeightField& field,
                      const Eigen::Vector3d& origin,
                      const Eigen::Vector3d& direction,
                      double t) {
  const auto g = [&](double s) {
    const Eigen::Vector3d p = origin + s * direction;
    return p.z() - field.Height(p.x(), p.y());
  };
  const double first = g(1e-6);
  for (double s = 1e-6; s < t * (1.0 - 1e-6); s += t / 20000.0) {
    const Eigen::Vector3d p = origin + s * direction;
    if (field.Contains(p.x(), p.y()) && g(s) * first <= 0.0) return false;
  }
  return true;
}

TEST(IntersectHeightField, HitsTheFirstCrossingOnTheSurface) {
  const TexturedHeightField field = ThreeHills();
  const HeightFieldBounds bounds = field.ComputeBounds();
  // Straight down: the hit is the height below.
  auto t = IntersectHeightField(field, bounds, {-1.5, 0.5, 10.0}, {0.0, 0.0, -2.0}, 100.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, (10.0 - field.Height(-1.5, 0.5)) / 2.0, 1e-9);
  // Random rays from above, some oblique enough to hit a hill's far side or to pass over the
  // near one.
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int num_hits = 0;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d origin(4.0 * unit(rng), 4.0 * unit(rng), 3.0 + unit(rng));
    const Eigen::Vector3d direction(unit(rng), unit(rng), -0.15 - 0.5 * std::abs(unit(rng)));
    t = IntersectHeightField(field, bounds, origin, direction, 1e9);
    if (!t) {
      // A miss leaves the rectangle above the surface.
      EXPECT_TRUE(NoCrossingBefore(field, origin, direction, 50.0)) << "ray " << i;
      continue;
    }
    ++num_hits;
    const Eigen::Vector3d p = origin + *t * direction;
    EXPECT_TRUE(field.Contains(p.x(), p.y()));
    EXPECT_NEAR(p.z(), field.Height(p.x(), p.y()), 1e-9);
    EXPECT_TRUE(NoCrossingBefore(field, origin, direction, *t)) << "ray " << i;
  }
  EXPECT_GT(num_hits, 100);
  // From below (two-sided), and t_max cuts the search short.
  t = IntersectHeightField(field, bounds, {2.0, -1.0, -3.0}, {0.0, 0.0, 1.0}, 100.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 3.0 + field.Height(2.0, -1.0), 1e-9);
  EXPECT_FALSE(IntersectHeightField(field, bounds, {2.0, -1.0, -3.0}, {0.0, 0.0, 1.0}, 3.0));
  // Pointing up, above everything, or outside the rectangle: no hit.
  EXPECT_FALSE(IntersectHeightField(field, bounds, {0.0, 0.0, 5.0}, {0.1, 0.0, 1.0}, 100.0));
  EXPECT_FALSE(IntersectHeightField(field, bounds, {-9.0, 0.0, 2.6}, {1.0, 0.0, 0.0}, 100.0));
  EXPECT_FALSE(IntersectHeightField(field, bounds, {6.0, 0.0, 5.0}, {0.0, 0.0, -1.0}, 100.0));
}

TEST(IntersectRay, FindsHeightFieldsAndTheNearerQuad) {
  TexturedScene scene;
  scene.height_fields.push_back(ThreeHills());
  auto hit = IntersectRay(scene, {2.0, -1.0, 8.0}, {0.0, 0.0, -1.0});
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, -1);
  EXPECT_EQ(hit->height_field, 0);
  EXPECT_NEAR(hit->point.z(), scene.height_fields[0].Height(2.0, -1.0), 1e-9);
  EXPECT_LT((hit->uv - Eigen::Vector2d(7.0, 4.0)).norm(), 1e-12);
  // A roof above the hill hides it.
  TexturedQuad roof;
  roof.origin = {1.0, -2.0, 4.0};
  roof.edge_u = {2.0, 0.0, 0.0};
  roof.edge_v = {0.0, 2.0, 0.0};
  scene.quads.push_back(roof);
  hit = IntersectRay(scene, {2.0, -1.0, 8.0}, {0.0, 0.0, -1.0});
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->quad, 0);
  EXPECT_EQ(hit->height_field, -1);
  EXPECT_NEAR(hit->distance, 4.0, 1e-12);
}

TEST(DistanceToHeightField, OffsetsAlongTheNormalAreExact) {
  const TexturedHeightField field = ThreeHills();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coordinate(-4.0, 4.0);
  for (int i = 0; i < 200; ++i) {
    const double x = coordinate(rng), y = coordinate(rng);
    const Eigen::Vector3d on_surface(x, y, field.Height(x, y));
    EXPECT_LT(DistanceToHeightField(field, on_surface), 1e-12);
    // The curvature radius is > 0.5 m here: offsets below it have their foot at (x, y).
    for (const double offset : {-0.2, -0.01, 0.001, 0.05, 0.3}) {
      const Eigen::Vector3d point = on_surface + offset * field.Normal(x, y);
      EXPECT_NEAR(DistanceToHeightField(field, point), std::abs(offset), 1e-9)
          << "at " << x << ", " << y << " offset " << offset;
    }
  }
}

TEST(DistanceToHeightField, AgreesWithABruteForceSearch) {
  const TexturedHeightField field = ThreeHills();
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0), height(-0.4, 0.4);
  for (int i = 0; i < 20; ++i) {
    const double x = coordinate(rng), y = coordinate(rng);
    const Eigen::Vector3d point(x, y, field.Height(x, y) + height(rng));
    // Coarse grid, then a fine one (5e-5 m) around its best sample: the fine grid's nearest
    // sample is within 3.5e-5 m of the true foot, which changes the distance by less than that.
    const auto search = [&](const Eigen::Vector2d& middle, double half_width, double step) {
      Eigen::Vector2d best_xy = middle;
      double best = std::numeric_limits<double>::infinity();
      for (double sx = middle.x() - half_width; sx <= middle.x() + half_width; sx += step) {
        for (double sy = middle.y() - half_width; sy <= middle.y() + half_width; sy += step) {
          const double d = (Eigen::Vector3d(sx, sy, field.Height(sx, sy)) - point).norm();
          if (d < best) {
            best = d;
            best_xy = {sx, sy};
          }
        }
      }
      return std::make_pair(best, best_xy);
    };
    const Eigen::Vector2d coarse = search({x, y}, 0.6, 0.005).second;
    const double brute = search(coarse, 0.01, 5e-5).first;
    const double distance = DistanceToHeightField(field, point);
    EXPECT_LE(distance, brute + 1e-12);
    EXPECT_GT(distance, brute - 3.5e-5) << "at " << point.transpose();
  }
  // Beyond the rectangle the nearest point is on its rim.
  const Eigen::Vector3d outside(7.0, 0.0, field.Height(5.0, 0.0));
  EXPECT_NEAR(DistanceToHeightField(field, outside), 2.0, 1e-3);
}

TEST(DistanceToQuad, InteriorEdgesAndCorners) {
  const TexturedQuad quad = TwoQuads().quads[0];  // [-1, 1] x [-0.5, 0.5] at z = 2.
  EXPECT_NEAR(DistanceToQuad(quad, {0.3, 0.2, 2.0}), 0.0, 1e-15);
  EXPECT_NEAR(DistanceToQuad(quad, {0.3, 0.2, 2.7}), 0.7, 1e-15);
  EXPECT_NEAR(DistanceToQuad(quad, {0.3, 0.2, 1.5}), 0.5, 1e-15);
  EXPECT_NEAR(DistanceToQuad(quad, {0.3, 0.9, 2.3}), 0.5, 1e-15);             // Beyond the +y edge.
  EXPECT_NEAR(DistanceToQuad(quad, {-1.3, 0.0, 2.4}), 0.5, 1e-15);            // Beyond the -x edge.
  EXPECT_NEAR(DistanceToQuad(quad, {2.0, 1.5, 2.0}), std::sqrt(2.0), 1e-15);  // Corner.
  // A skewed parallelogram: the nearest point beyond an oblique edge.
  TexturedQuad skewed;
  skewed.edge_u = {2.0, 0.0, 0.0};
  skewed.edge_v = {1.0, 1.0, 0.0};
  EXPECT_NEAR(DistanceToQuad(skewed, {0.0, 1.0, 0.0}), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(DistanceToQuad(skewed, {2.5, 0.5, 0.0}), 0.0, 1e-15);
}

TEST(DistanceToScene, NearestOfAllSurfaces) {
  TexturedScene scene = TwoQuads();
  EXPECT_EQ(DistanceToScene(TexturedScene(), Eigen::Vector3d::Zero()),
            std::numeric_limits<double>::infinity());
  EXPECT_NEAR(DistanceToScene(scene, {0.0, 0.0, 0.0}), 2.0, 1e-15);
  EXPECT_NEAR(DistanceToScene(scene, {0.0, 0.0, 4.0}), 1.0, 1e-15);
  scene.height_fields.push_back(ThreeHills());
  // Just above the hill at (2, -1), 2 m below the far quad: the hill is nearest.
  const double z = scene.height_fields[0].Height(2.0, -1.0) + 0.01;
  EXPECT_NEAR(DistanceToScene(scene, {2.0, -1.0, z}), 0.01, 1e-3);
}

TEST(MakeTerrainScene, HillsWithModerateSlopesDeterministicFromSeed) {
  const TexturedScene a = MakeTerrainScene(1), b = MakeTerrainScene(1), c = MakeTerrainScene(2);
  std::string error;
  ASSERT_TRUE(a.Check(&error)) << error;
  ASSERT_EQ(a.height_fields.size(), 1u);
  EXPECT_TRUE(a.quads.empty());
  const TexturedHeightField& field = a.height_fields[0];
  EXPECT_EQ(field.hills.size(), 12u);
  EXPECT_EQ(field.hills[5].center, b.height_fields[0].hills[5].center);
  EXPECT_NE(field.hills[5].center, c.height_fields[0].hills[5].center);
  double min_z = 1e9, max_z = -1e9, max_slope = 0.0;
  for (double x = -12.0; x <= 12.0; x += 0.1) {
    for (double y = -12.0; y <= 12.0; y += 0.1) {
      Eigen::Vector2d g;
      const double z = field.Evaluate(x, y, &g);
      min_z = std::min(min_z, z);
      max_z = std::max(max_z, z);
      max_slope = std::max(max_slope, g.norm());
    }
  }
  // Relief of metres, slopes that stay matchable from above.
  EXPECT_GT(max_z - min_z, 1.5);
  EXPECT_LT(max_z - min_z, 5.0);
  EXPECT_GT(std::atan(max_slope) * 180.0 / M_PI, 10.0);
  EXPECT_LT(std::atan(max_slope) * 180.0 / M_PI, 40.0);
}

TEST(TerrainCameraGrid, NadirCamerasOnAGrid) {
  const std::vector<Rigid3d> poses = TerrainCameraGrid(2, 3, 4.0, 12.0);
  ASSERT_EQ(poses.size(), 6u);
  EXPECT_LT((poses[0].CenterInWorld() - Eigen::Vector3d(-4.0, -2.0, 12.0)).norm(), 1e-12);
  EXPECT_LT((poses[5].CenterInWorld() - Eigen::Vector3d(4.0, 2.0, 12.0)).norm(), 1e-12);
  for (const Rigid3d& pose : poses) {
    // The optical axis points down; image "up" (-y) is world +y.
    EXPECT_LT(
        (pose.rotation.inverse() * Eigen::Vector3d::UnitZ() + Eigen::Vector3d::UnitZ()).norm(),
        1e-12);
    EXPECT_LT(
        (pose.rotation.inverse() * -Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY()).norm(),
        1e-12);
  }
  EXPECT_THROW(TerrainCameraGrid(0, 3, 1.0, 1.0), CheckError);
}

}  // namespace
}  // namespace reconduit
