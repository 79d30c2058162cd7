#include "core/estimators/pose.h"

#include "core/util/cancel.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

namespace reconduit {
namespace {

TEST(AbsolutePoseOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(AbsolutePoseOptions().Check(&error)) << error;
  AbsolutePoseOptions options;
  options.min_num_inliers = 3;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_num_inliers"), std::string::npos);
}

struct PoseScene {
  Camera camera;
  Rigid3d cam_from_world;
  std::vector<Eigen::Vector2d> points2D;
  std::vector<Eigen::Vector3d> points3D;
  std::vector<char> is_inlier;
};

// Alternating inliers (0.5 px noise) and outliers (random pixels for valid 3-D points).
PoseScene MakeScene(int num_inliers, int num_outliers, unsigned seed) {
  PoseScene scene;
  scene.camera = Camera::FromFocal(1200, 900, 1000.0);
  scene.camera.k1 = -0.05;  // Exercises the undistortion path.
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.5);
  scene.cam_from_world =
      Rigid3d::LookAt({2.0 * u(rng), 1.0 * u(rng), -7.0}, {0, 0, 0}, -Eigen::Vector3d::UnitY());
  int inliers = 0, outliers = 0;
  while (inliers < num_inliers || outliers < num_outliers) {
    const Eigen::Vector3d X(2 * u(rng), 2 * u(rng), 2 * u(rng));
    const auto pixel = scene.camera.ImgFromCam(scene.cam_from_world * X);
    if (!pixel || !scene.camera.InImage(*pixel)) continue;
    const bool inlier = inliers < num_inliers && (outliers >= num_outliers || inliers <= outliers);
    scene.points3D.push_back(X);
    if (inlier) {
      scene.points2D.push_back(*pixel + Eigen::Vector2d(noise(rng), noise(rng)));
      ++inliers;
    } else {
      scene.points2D.emplace_back((u(rng) + 1) * 600, (u(rng) + 1) * 450);
      ++outliers;
    }
    scene.is_inlier.push_back(inlier ? 1 : 0);
  }
  return scene;
}

TEST(EstimateAbsolutePose, RecoversThePoseWithHalfOutliers) {
  for (unsigned seed = 0; seed < 5; ++seed) {
    const PoseScene scene = MakeScene(100, 100, seed);
    const auto report =
        EstimateAbsolutePose(scene.camera, scene.points2D, scene.points3D, AbsolutePoseOptions());
    ASSERT_TRUE(report.success) << report.message;
    EXPECT_LT(RotationDifferenceDeg(report.cam_from_world, scene.cam_from_world), 0.1);
    EXPECT_LT((report.cam_from_world.CenterInWorld() - scene.cam_from_world.CenterInWorld()).norm(),
              0.02);  // 7 units away: 0.3 %.
    std::size_t true_positives = 0;
    for (std::size_t i = 0; i < scene.is_inlier.size(); ++i) {
      true_positives += report.inlier_mask[i] && scene.is_inlier[i];
    }
    EXPECT_GT(double(true_positives) / report.num_inliers, 0.95) << "precision, seed " << seed;
    EXPECT_GT(double(true_positives) / 100.0, 0.95) << "recall, seed " << seed;
  }
}

TEST(EstimateAbsolutePose, TooFewOrDegenerateInputFailsWithMessage) {
  const PoseScene scene = MakeScene(2, 0, 1);
  const auto few = EstimateAbsolutePose(scene.camera, scene.points2D, scene.points3D, {});
  EXPECT_FALSE(few.success);
  EXPECT_FALSE(few.message.empty());
  // All 3-D points identical: every sample is degenerate.
  const std::vector<Eigen::Vector3d> same(20, Eigen::Vector3d(0, 0, 5));
  const std::vector<Eigen::Vector2d> pixels(20, Eigen::Vector2d(600, 450));
  const auto degenerate = EstimateAbsolutePose(scene.camera, pixels, same, {});
  EXPECT_FALSE(degenerate.success);
  EXPECT_FALSE(degenerate.message.empty());
}

TEST(EstimateAbsolutePose, Cancellation) {
  const PoseScene scene = MakeScene(50, 50, 2);
  CancelToken token;
  token.RequestCancel();
  const auto report =
      EstimateAbsolutePose(scene.camera, scene.points2D, scene.points3D, {}, &token);
  EXPECT_FALSE(report.success);
  EXPECT_TRUE(report.canceled);
}

}  // namespace
}  // namespace reconduit
