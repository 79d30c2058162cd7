#include "core/estimators/solvers/homography_matrix.h"

#include "core/estimators/synthetic_two_view_test_util.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

namespace reconduit {
namespace {

using testing_util::DistanceUpToScale;
using testing_util::MakeTwoViewScene;
using testing_util::SceneKind;

TEST(HomographyMatrixEstimator, RecoversThePlaneHomographyFromFourPoints) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const auto scene = MakeTwoViewScene(SceneKind::kPlanar, 50, 0, 0.0, seed);
    const std::vector<Eigen::Vector2d> p1(scene.points1.begin(), scene.points1.begin() + 4);
    const std::vector<Eigen::Vector2d> p2(scene.points2.begin(), scene.points2.begin() + 4);
    std::vector<Eigen::Matrix3d> models;
    HomographyMatrixEstimator::Estimate(p1, p2, &models);
    ASSERT_EQ(models.size(), 1u) << "seed " << seed;
    EXPECT_LT(DistanceUpToScale(models[0], scene.H), 1e-9) << "seed " << seed;
    std::vector<double> residuals;
    HomographyMatrixEstimator::Residuals(scene.points1, scene.points2, models[0], &residuals);
    for (const double r : residuals) EXPECT_LT(r, 1e-14);  // pixels², on all 50 points
  }
}

TEST(HomographyMatrixEstimator, RecoversTheInfiniteHomographyOfARotation) {
  const auto scene = MakeTwoViewScene(SceneKind::kRotation, 30, 0, 0.0, 21);
  std::vector<Eigen::Matrix3d> models;
  HomographyMatrixEstimator::Estimate(scene.points1, scene.points2, &models);
  ASSERT_EQ(models.size(), 1u);
  EXPECT_LT(DistanceUpToScale(models[0], scene.H), 1e-9);
}

TEST(HomographyMatrixEstimator, DegenerateSamplesGiveNoModel) {
  std::vector<Eigen::Matrix3d> models;
  const std::vector<Eigen::Vector2d> same(4, Eigen::Vector2d(3, 4));
  HomographyMatrixEstimator::Estimate(same, same, &models);
  EXPECT_TRUE(models.empty());
  // Three collinear points (and the fourth anywhere): H is not determined.
  const std::vector<Eigen::Vector2d> p1 = {{0, 0}, {10, 10}, {20, 20}, {50, 0}};
  const std::vector<Eigen::Vector2d> p2 = {{5, 1}, {15, 11}, {25, 21}, {40, 7}};
  HomographyMatrixEstimator::Estimate(p1, p2, &models);
  EXPECT_TRUE(models.empty());
  const std::vector<Eigen::Vector2d> three(3, Eigen::Vector2d(1, 2));
  EXPECT_THROW(HomographyMatrixEstimator::Estimate(three, three, &models), CheckError);
}

TEST(HomographyMatrixEstimator, ResidualsAreSymmetricTransferErrors) {
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  H(0, 2) = 5.0;  // x2 = x1 + (5, 0).
  std::vector<double> residuals;
  HomographyMatrixEstimator::Residuals({{0, 0}, {10, 3}}, {{6, 0}, {15, 3}}, H, &residuals);
  ASSERT_EQ(residuals.size(), 2u);
  EXPECT_DOUBLE_EQ(residuals[0], 2.0);  // 1² forward + 1² backward
  EXPECT_DOUBLE_EQ(residuals[1], 0.0);
  HomographyMatrixEstimator::Residuals({{0, 0}}, {{0, 0}}, Eigen::Matrix3d::Zero(), &residuals);
  EXPECT_EQ(residuals[0], std::numeric_limits<double>::max());
}

TEST(ComputeHomographySquaredSampsonError, IsTheGeometricErrorForATranslation) {
  // For x2 = x1 + c the variety is flat, so the Sampson error is exact: an offset (1, 0) is
  // split between the two points, (1/2)² + (1/2)² = 0.5.
  Eigen::Matrix3d H = Eigen::Matrix3d::Identity();
  H(0, 2) = 5.0;
  std::vector<double> residuals;
  ComputeHomographySquaredSampsonError({{0, 0}, {10, 3}, {1, 1}}, {{6, 0}, {15, 3}, {7, 3}}, H,
                                       &residuals);
  EXPECT_NEAR(residuals[0], 0.5, 1e-12);
  EXPECT_NEAR(residuals[1], 0.0, 1e-12);
  EXPECT_NEAR(residuals[2], 2.5, 1e-12);  // Offset (1, 2): (1 + 4) / 2.
}

}  // namespace
}  // namespace reconduit
