#include "core/estimators/triangulation.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace reconduit {
namespace {

Eigen::Vector2d Project(const Rigid3d& cam_from_world, const Eigen::Vector3d& X) {
  return (cam_from_world * X).hnormalized();
}

TEST(TriangulatePoint, RecoversExactPoints) {
  const Rigid3d cam1;
  const Rigid3d cam2 = Rigid3d::LookAt({1.0, 0.0, 0.0}, {0.0, 0.0, 5.0}, -Eigen::Vector3d::UnitY());
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d X(u(rng), u(rng), 5.0 + 2.0 * u(rng));
    const auto dlt =
        TriangulatePoint(cam1.ToMatrix(), cam2.ToMatrix(), Project(cam1, X), Project(cam2, X));
    ASSERT_TRUE(dlt.has_value());
    EXPECT_LT((*dlt - X).norm(), 1e-9);
    const auto mid = TriangulateMidPoint(cam1, cam2, Project(cam1, X), Project(cam2, X));
    ASSERT_TRUE(mid.has_value());
    EXPECT_LT((*mid - X).norm(), 1e-9);
    EXPECT_TRUE(HasPositiveDepth(cam1, X));
    EXPECT_TRUE(HasPositiveDepth(cam2, X));
  }
}

TEST(TriangulatePoint, NoisyObservationsGiveNearbyPoints) {
  const Rigid3d cam1;
  const Rigid3d cam2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-1.0, 0.0, 0.0));
  const Eigen::Vector3d X(0.2, -0.1, 4.0);
  const Eigen::Vector2d noise(1e-3, -1e-3);  // ~1 px at f = 1000.
  const auto dlt = TriangulatePoint(cam1.ToMatrix(), cam2.ToMatrix(), Project(cam1, X) + noise,
                                    Project(cam2, X) - noise);
  const auto mid =
      TriangulateMidPoint(cam1, cam2, Project(cam1, X) + noise, Project(cam2, X) - noise);
  ASSERT_TRUE(dlt && mid);
  // Depth error ~ z² / baseline * disparity error = 16 * 2e-3.
  EXPECT_LT((*dlt - X).norm(), 0.05);
  EXPECT_LT((*mid - X).norm(), 0.05);
  EXPECT_GT((*dlt - X).norm(), 0.0);
}

TEST(TriangulatePoint, ParallelRaysGiveNoPoint) {
  const Rigid3d cam1;
  const Rigid3d cam2(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-1.0, 0.0, 0.0));
  // The same direction in both cameras: the point is at infinity.
  EXPECT_FALSE(TriangulateMidPoint(cam1, cam2, {0.1, 0.2}, {0.1, 0.2}).has_value());
  EXPECT_FALSE(TriangulatePoint(cam1.ToMatrix(), cam2.ToMatrix(), {0.1, 0.2}, {0.1, 0.2}));
}

TEST(CalculateTriangulationAngle, KnownConfigurations) {
  EXPECT_NEAR(CalculateTriangulationAngle({-1, 0, 0}, {1, 0, 0}, {0, 0, 1}), M_PI / 2, 1e-12);
  EXPECT_NEAR(CalculateTriangulationAngle({0, 0, 0}, {1, 0, 0}, {0, 0, 1}), M_PI / 4, 1e-12);
  EXPECT_NEAR(CalculateTriangulationAngle({0, 0, 0}, {1e-6, 0, 0}, {0, 0, 1}), 1e-6, 1e-15);
  EXPECT_EQ(CalculateTriangulationAngle({0, 0, 0}, {1, 0, 0}, {0, 0, 0}), 0.0);
}

TEST(HasPositiveDepth, PointsBehindTheCameraAreRejected) {
  const Rigid3d cam;
  EXPECT_TRUE(HasPositiveDepth(cam, {0, 0, 1}));
  EXPECT_FALSE(HasPositiveDepth(cam, {0, 0, -1}));
  EXPECT_FALSE(HasPositiveDepth(cam, {1, 0, 0}));
}

Eigen::Vector2d ProjectNormalized(const Rigid3d& cam_from_world, const Eigen::Vector3d& x) {
  const Eigen::Vector3d c = cam_from_world * x;
  return c.head<2>() / c.z();
}

TEST(TriangulatePointMultiView, ExactWithoutNoise) {
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  const Rigid3d b = Rigid3d::LookAt({2, 0.5, -4.5}, {0, 0, 0});
  const Rigid3d c = Rigid3d::LookAt({-1, 1, -5}, {0, 0, 0});
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d x(u(rng), u(rng), u(rng));
    const auto two = TriangulatePoint(std::vector<Rigid3d>{a, b},
                                      {ProjectNormalized(a, x), ProjectNormalized(b, x)});
    ASSERT_TRUE(two.has_value());
    EXPECT_LT((*two - x).norm(), 1e-9);
    const auto three = TriangulatePoint(
        std::vector<Rigid3d>{a, b, c},
        {ProjectNormalized(a, x), ProjectNormalized(b, x), ProjectNormalized(c, x)});
    ASSERT_TRUE(three.has_value());
    EXPECT_LT((*three - x).norm(), 1e-9);
  }
}

TEST(TriangulatePointMultiView, SameCentreHasNoParallax) {
  const Rigid3d a = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0});
  const Rigid3d b = Rigid3d::LookAt({0, 0, -5}, {1, 0, 0});
  const Eigen::Vector3d x(0.1, 0.1, 0);
  const auto p = TriangulatePoint(std::vector<Rigid3d>{a, b},
                                  {ProjectNormalized(a, x), ProjectNormalized(b, x)});
  if (p.has_value()) {
    EXPECT_LT(CalculateTriangulationAngle(a.CenterInWorld(), b.CenterInWorld(), *p), 1e-6)
        << "any answer has no parallax, so the mapper's angle check rejects it";
  }
}

TEST(TriangulatePointMultiView, NeedsTwoViews) {
  EXPECT_THROW(TriangulatePoint(std::vector<Rigid3d>{Rigid3d()}, {Eigen::Vector2d(0, 0)}),
               CheckError);
}

}  // namespace
}  // namespace reconduit
