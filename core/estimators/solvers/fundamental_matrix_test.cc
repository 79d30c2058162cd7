#include "core/estimators/solvers/fundamental_matrix.h"

#include "core/estimators/synthetic_two_view_test_util.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace reconduit {
namespace {

using testing_util::DistanceUpToScale;
using testing_util::MakeTwoViewScene;
using testing_util::SceneKind;

double MaxAbsEpipolar(const std::vector<Eigen::Vector2d>& p1,
                      const std::vector<Eigen::Vector2d>& p2,
                      const Eigen::Matrix3d& F) {
  // Algebraic error in normalised image coordinates (K^-1 pixels) for unit-norm F, so
  // that the tolerance is independent of the pixel scale: x2n^T (K^T F K) x1n.
  const Eigen::Matrix3d K = Camera::FromFocal(1000, 800, 900.0).K();
  const Eigen::Matrix3d K_inv = K.inverse();
  Eigen::Matrix3d E = K.transpose() * F * K;
  E /= E.norm();
  double max_error = 0.0;
  for (std::size_t i = 0; i < p1.size(); ++i) {
    const Eigen::Vector3d x1 = K_inv * p1[i].homogeneous();
    const Eigen::Vector3d x2 = K_inv * p2[i].homogeneous();
    max_error = std::max(max_error, std::abs(x2.dot(E * x1)));
  }
  return max_error;
}

TEST(FundamentalSevenPointEstimator, RecoversTheTrueFFromExactPoints) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 60, 0, 0.0, seed);
    const std::vector<Eigen::Vector2d> p1(scene.points1.begin(), scene.points1.begin() + 7);
    const std::vector<Eigen::Vector2d> p2(scene.points2.begin(), scene.points2.begin() + 7);
    std::vector<Eigen::Matrix3d> models;
    FundamentalMatrixSevenPointEstimator::Estimate(p1, p2, &models);
    ASSERT_GE(models.size(), 1u);
    ASSERT_LE(models.size(), 3u);
    double best = 1e9;
    const Eigen::Matrix3d* best_model = nullptr;
    for (const auto& F : models) {
      // Every model satisfies the 7 constraints and is singular.
      EXPECT_LT(MaxAbsEpipolar(p1, p2, F), 1e-9) << "seed " << seed;
      EXPECT_LT(std::abs(F.determinant()) / std::pow(F.norm(), 3), 1e-9);
      const double d = DistanceUpToScale(F, scene.F);
      if (d < best) {
        best = d;
        best_model = &F;
      }
    }
    EXPECT_LT(best, 1e-6) << "seed " << seed;
    // The true model also holds on the 53 points it was not fitted to.
    EXPECT_LT(MaxAbsEpipolar(scene.points1, scene.points2, *best_model), 1e-9);
    std::vector<double> residuals;
    FundamentalMatrixSevenPointEstimator::Residuals(scene.points1, scene.points2, *best_model,
                                                    &residuals);
    for (const double r : residuals) EXPECT_LT(r, 1e-12);  // pixels²
  }
}

TEST(FundamentalSevenPointEstimator, DegenerateSamplesGiveNoModel) {
  std::vector<Eigen::Matrix3d> models;
  // Coincident points.
  const std::vector<Eigen::Vector2d> same(7, Eigen::Vector2d(100, 200));
  FundamentalMatrixSevenPointEstimator::Estimate(same, same, &models);
  EXPECT_TRUE(models.empty());
  // Noise-free points on one plane: the epipolar system has a 3-D null space.
  const auto planar = MakeTwoViewScene(SceneKind::kPlanar, 7, 0, 0.0, 3);
  FundamentalMatrixSevenPointEstimator::Estimate(planar.points1, planar.points2, &models);
  EXPECT_TRUE(models.empty());
  // Wrong sample size is a precondition violation.
  const std::vector<Eigen::Vector2d> six(6, Eigen::Vector2d(1, 2));
  EXPECT_THROW(FundamentalMatrixSevenPointEstimator::Estimate(six, six, &models), CheckError);
}

TEST(FundamentalEightPointEstimator, RecoversTheTrueFFromExactPoints) {
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 100, 0, 0.0, 11);
  std::vector<Eigen::Matrix3d> models;
  FundamentalMatrixEightPointEstimator::Estimate(scene.points1, scene.points2, &models);
  ASSERT_EQ(models.size(), 1u);
  EXPECT_LT(DistanceUpToScale(models[0], scene.F), 1e-9);
  EXPECT_LT(MaxAbsEpipolar(scene.points1, scene.points2, models[0]), 1e-9);
  EXPECT_LT(std::abs(models[0].determinant()), 1e-12);
}

TEST(FundamentalEightPointEstimator, NoisyPointsGiveSmallSampsonErrors) {
  const double kNoise = 0.5;  // pixels
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 300, 0, kNoise, 12);
  std::vector<Eigen::Matrix3d> models;
  FundamentalMatrixEightPointEstimator::Estimate(scene.points1, scene.points2, &models);
  ASSERT_EQ(models.size(), 1u);
  std::vector<double> residuals;
  FundamentalMatrixEightPointEstimator::Residuals(scene.points1, scene.points2, models[0],
                                                  &residuals);
  double sum = 0.0;
  for (const double r : residuals) sum += r;
  // The Sampson error has one degree of freedom: E[r] = sigma² (a little less after fitting).
  EXPECT_LT(sum / residuals.size(), 1.5 * kNoise * kNoise);
  EXPECT_GT(sum / residuals.size(), 0.5 * kNoise * kNoise);
  EXPECT_LT(DistanceUpToScale(models[0], scene.F), 0.05);
}

TEST(FundamentalEightPointEstimator, RefineStaysNearTheCleanOptimumWithMismatchesInTheBand) {
  // 150 inliers with 0.5 px noise plus 15 mismatches 2.9 px off their epipolar lines (on
  // alternating sides), just inside the 3 px band, as in LO-RANSAC inlier sets. After Refine
  // the clean inliers' mean squared Sampson error stays within 10 % of that of the 8-point
  // fit to the clean inliers alone.
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 150, 0, 0.5, 13);
  std::vector<Eigen::Vector2d> p1 = scene.points1, p2 = scene.points2;
  const auto mismatches = MakeTwoViewScene(SceneKind::kGeneral, 15, 0, 0.0, 14);
  for (std::size_t i = 0; i < 15; ++i) {
    p1.push_back(mismatches.points1[i]);
    // Slide along the epipolar line by a large amount and off it by 2.9 px.
    const Eigen::Vector3d line = scene.F * mismatches.points1[i].homogeneous();
    const Eigen::Vector2d normal = line.head<2>().normalized();
    const Eigen::Vector2d along(-normal.y(), normal.x());
    p2.push_back(mismatches.points2[i] + 150.0 * along + (i % 2 ? 2.9 : -2.9) * normal);
  }
  const auto clean_mean = [&](const Eigen::Matrix3d& F) {
    std::vector<double> residuals;
    ComputeSquaredSampsonError(scene.points1, scene.points2, F, &residuals);
    double sum = 0.0;
    for (const double r : residuals) sum += r;
    return sum / residuals.size();
  };
  std::vector<Eigen::Matrix3d> clean_models, models;
  FundamentalMatrixEightPointEstimator::Estimate(scene.points1, scene.points2, &clean_models);
  FundamentalMatrixEightPointEstimator::Estimate(p1, p2, &models);
  ASSERT_EQ(models.size(), 1u);
  ASSERT_EQ(clean_models.size(), 1u);
  Eigen::Matrix3d refined = models[0];
  FundamentalMatrixEightPointEstimator::Refine(p1, p2, &refined);
  EXPECT_LT(clean_mean(refined), 1.10 * clean_mean(clean_models[0]));
  EXPECT_LT(clean_mean(refined), 1.5 * 0.25);

  const auto exact = MakeTwoViewScene(SceneKind::kGeneral, 50, 0, 0.0, 15);
  Eigen::Matrix3d F = exact.F;
  FundamentalMatrixEightPointEstimator::Refine(exact.points1, exact.points2, &F);
  EXPECT_LT(DistanceUpToScale(F, exact.F), 1e-9);
}

TEST(ComputeSquaredSampsonError, MatchesTheClosedFormForRectifiedStereo) {
  // Pure x translation: F = [e]x with e = (1, 0, 0); x2^T F x1 = v1 - v2 and the Sampson
  // error is (v1 - v2)² / 2: the offset is shared equally by the two points.
  Eigen::Matrix3d F;
  F << 0, 0, 0, 0, 0, -1, 0, 1, 0;
  std::vector<double> residuals;
  ComputeSquaredSampsonError({{10, 20}, {5, 5}}, {{50, 23}, {-7, 5}}, F, &residuals);
  ASSERT_EQ(residuals.size(), 2u);
  EXPECT_DOUBLE_EQ(residuals[0], 4.5);
  EXPECT_DOUBLE_EQ(residuals[1], 0.0);
  // A zero matrix has no gradient: every residual is "infinitely" large.
  ComputeSquaredSampsonError({{1, 2}}, {{3, 4}}, Eigen::Matrix3d::Zero(), &residuals);
  EXPECT_EQ(residuals[0], std::numeric_limits<double>::max());
}

}  // namespace
}  // namespace reconduit
