#include "core/estimators/normalization.h"

#include "core/estimators/polynomial.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace reconduit {
namespace {

TEST(CenterAndNormalizeImagePoints, CentroidZeroMeanDistanceSqrt2) {
  const std::vector<Eigen::Vector2d> points = {{100, 200}, {300, 250}, {150, 600}, {900, 10}};
  std::vector<Eigen::Vector2d> normalized;
  Eigen::Matrix3d T;
  ASSERT_TRUE(CenterAndNormalizeImagePoints(points, &normalized, &T));
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  double mean_distance = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    centroid += normalized[i];
    mean_distance += normalized[i].norm();
    EXPECT_LT(((T * points[i].homogeneous()).hnormalized() - normalized[i]).norm(), 1e-12);
  }
  EXPECT_LT(centroid.norm(), 1e-12);
  EXPECT_NEAR(mean_distance / points.size(), std::sqrt(2.0), 1e-12);
}

TEST(CenterAndNormalizeImagePoints, CoincidentPointsFail) {
  std::vector<Eigen::Vector2d> normalized;
  Eigen::Matrix3d T;
  EXPECT_FALSE(CenterAndNormalizeImagePoints({{5, 5}, {5, 5}, {5, 5}}, &normalized, &T));
  EXPECT_FALSE(CenterAndNormalizeImagePoints({}, &normalized, &T));
}

TEST(RealPolynomialRoots, CubicQuadraticAndLinear) {
  // (x - 1)(x + 2)(x - 3) = x³ - 2x² - 5x + 6.
  std::vector<double> roots = RealPolynomialRoots(Eigen::Vector4d(1, -2, -5, 6));
  std::sort(roots.begin(), roots.end());
  ASSERT_EQ(roots.size(), 3u);
  EXPECT_NEAR(roots[0], -2, 1e-12);
  EXPECT_NEAR(roots[1], 1, 1e-12);
  EXPECT_NEAR(roots[2], 3, 1e-12);
  // x² + 1 has no real roots; a zero leading coefficient lowers the degree.
  EXPECT_TRUE(RealPolynomialRoots(Eigen::Vector3d(1, 0, 1)).empty());
  roots = RealPolynomialRoots(Eigen::Vector4d(0, 0, 2, -4));
  ASSERT_EQ(roots.size(), 1u);
  EXPECT_NEAR(roots[0], 2, 1e-15);
  EXPECT_TRUE(RealPolynomialRoots(Eigen::Vector3d::Zero()).empty());
}

}  // namespace
}  // namespace reconduit
