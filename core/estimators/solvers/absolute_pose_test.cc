#include "core/estimators/solvers/absolute_pose.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace reconduit {
namespace {

struct PoseData {
  Rigid3d cam_from_world;
  std::vector<Eigen::Vector2d> points2D;  // Normalised.
  std::vector<Eigen::Vector3d> points3D;
};

PoseData MakePoseData(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PoseData data;
  data.cam_from_world =
      Rigid3d::LookAt(Eigen::Vector3d(u(rng), u(rng), -6.0 + u(rng)),
                      Eigen::Vector3d(0.1 * u(rng), 0.1 * u(rng), 0.0), -Eigen::Vector3d::UnitY());
  while (static_cast<int>(data.points3D.size()) < n) {
    const Eigen::Vector3d X(2 * u(rng), 2 * u(rng), 2 * u(rng));
    const Eigen::Vector3d x = data.cam_from_world * X;
    if (x.z() < 1.0) continue;
    data.points3D.push_back(X);
    data.points2D.push_back(x.hnormalized());
  }
  return data;
}

double PoseError(const Matrix3x4d& estimate, const Rigid3d& truth) {
  return (estimate - truth.ToMatrix()).norm();
}

TEST(P3PEstimator, OneSolutionIsTheTruePose) {
  for (unsigned seed = 0; seed < 20; ++seed) {
    const PoseData data = MakePoseData(3, seed);
    std::vector<Matrix3x4d> models;
    P3PEstimator::Estimate(data.points2D, data.points3D, &models);
    ASSERT_GE(models.size(), 1u) << "seed " << seed;
    ASSERT_LE(models.size(), 4u);
    double best = 1e9;
    for (const auto& model : models) best = std::min(best, PoseError(model, data.cam_from_world));
    EXPECT_LT(best, 1e-6) << "seed " << seed;
  }
}

TEST(P3PEstimator, CollinearPointsGiveNoModel) {
  const std::vector<Eigen::Vector3d> points3D = {{0, 0, 5}, {1, 1, 5}, {2, 2, 5}};
  const std::vector<Eigen::Vector2d> points2D = {{0, 0}, {0.2, 0.2}, {0.4, 0.4}};
  std::vector<Matrix3x4d> models;
  P3PEstimator::Estimate(points2D, points3D, &models);
  EXPECT_TRUE(models.empty());
  EXPECT_THROW(P3PEstimator::Estimate({{0, 0}}, {{0, 0, 1}}, &models), CheckError);
}

TEST(P3PEstimator, ResidualsAreSquaredNormalisedReprojectionErrors) {
  Matrix3x4d identity = Matrix3x4d::Zero();
  identity.leftCols<3>().setIdentity();
  std::vector<double> residuals;
  P3PEstimator::Residuals({{0.1, 0.0}, {0.0, 0.0}}, {{0.0, 0.0, 2.0}, {0.0, 0.0, -2.0}}, identity,
                          &residuals);
  EXPECT_NEAR(residuals[0], 0.01, 1e-15);
  EXPECT_EQ(residuals[1], std::numeric_limits<double>::max());  // Behind the camera.
}

TEST(PnPNonMinimalEstimator, RecoversAndRefinesThePose) {
  PoseData data = MakePoseData(50, 42);
  std::vector<Matrix3x4d> models;
  PnPNonMinimalEstimator::Estimate(data.points2D, data.points3D, &models);
  ASSERT_EQ(models.size(), 1u);
  EXPECT_LT(PoseError(models[0], data.cam_from_world), 1e-6);

  // Refine from a perturbed pose converges back.
  Matrix3x4d perturbed = data.cam_from_world.ToMatrix();
  perturbed.col(3) += Eigen::Vector3d(0.05, -0.03, 0.1);
  PnPNonMinimalEstimator::Refine(data.points2D, data.points3D, &perturbed);
  EXPECT_LT(PoseError(perturbed, data.cam_from_world), 1e-6);
}

}  // namespace
}  // namespace reconduit
