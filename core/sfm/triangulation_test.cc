#include "core/sfm/triangulation.h"

#include <gtest/gtest.h>

#include <random>

#include "core/util/logging.h"

namespace reconduit {
namespace {

Eigen::Vector2d Project(const Rigid3d& cam_from_world, const Eigen::Vector3d& x) {
  const Eigen::Vector3d c = cam_from_world * x;
  return c.head<2>() / c.z();
}

TEST(TriangulatePoint, ExactWithoutNoise) {
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  const Rigid3d b = Rigid3d::LookAt({2, 0.5, -4.5}, {0, 0, 0});
  const Rigid3d c = Rigid3d::LookAt({-1, 1, -5}, {0, 0, 0});
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d x(u(rng), u(rng), u(rng));
    const auto two = TriangulatePoint({a, b}, {Project(a, x), Project(b, x)});
    ASSERT_TRUE(two.has_value());
    EXPECT_LT((*two - x).norm(), 1e-9);
    const auto three = TriangulatePoint({a, b, c}, {Project(a, x), Project(b, x), Project(c, x)});
    ASSERT_TRUE(three.has_value());
    EXPECT_LT((*three - x).norm(), 1e-9);
  }
}

TEST(TriangulatePoint, NoisyObservationsLandNearby) {
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  const Rigid3d b = Rigid3d::LookAt({2, 0, -5}, {0, 0, 0});
  const Eigen::Vector3d x(0.3, -0.2, 0.1);
  const Eigen::Vector2d noise(0.5 / 1000, -0.5 / 1000);  // Half a pixel at f = 1000.
  const auto p = TriangulatePoint({a, b}, {Project(a, x) + noise, Project(b, x) - noise});
  ASSERT_TRUE(p.has_value());
  EXPECT_LT((*p - x).norm(), 0.02);
}

TEST(TriangulatePoint, SameCentreIsDegenerate) {
  // Pure rotation: the two rays meet only at the centre; depth is undetermined.
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  const Rigid3d b = Rigid3d::LookAt({0, 0, -5}, {1, 0, 0});
  const Eigen::Vector3d x(0.1, 0.1, 0);
  const auto p = TriangulatePoint({a, b}, {Project(a, x), Project(b, x)});
  if (p.has_value()) {
    EXPECT_LT(TriangulationAngleDeg(a.CenterInWorld(), b.CenterInWorld(), *p), 1e-6)
        << "any answer has no parallax, so the mapper's angle check rejects it";
  }
}

TEST(TriangulationAngleDeg, RightAngle) {
  EXPECT_NEAR(TriangulationAngleDeg({1, 0, 0}, {0, 1, 0}, {0, 0, 0}), 90.0, 1e-12);
  EXPECT_NEAR(TriangulationAngleDeg({1, 0, 0}, {2, 0, 0}, {0, 0, 0}), 0.0, 1e-6);
}

TEST(HasPositiveDepth, FrontAndBack) {
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  EXPECT_TRUE(HasPositiveDepth(a, {0, 0, 0}));
  EXPECT_FALSE(HasPositiveDepth(a, {0, 0, -10}));
}

TEST(TriangulatePoint, NeedsTwoViews) {
  EXPECT_THROW(TriangulatePoint({Rigid3d()}, {Eigen::Vector2d(0, 0)}), CheckError);
}

}  // namespace
}  // namespace reconduit
