#include "core/sfm/self_calibration.h"

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include <random>

namespace reconduit {
namespace {

constexpr int kWidth = 1600, kHeight = 1200;
constexpr double kFocal = 1400.0;

// F between two views of random points in a box, estimated by the normalised 8-point
// algorithm from projections with Gaussian pixel noise.
Eigen::Matrix3d NoisyFundamental(const Rigid3d& cam1_from_world,
                                 const Rigid3d& cam2_from_world,
                                 double noise_px,
                                 std::mt19937& rng) {
  const Camera camera = Camera::FromFocal(kWidth, kHeight, kFocal);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  std::normal_distribution<double> n(0.0, noise_px);
  std::vector<cv::Point2d> p1, p2;
  while (p1.size() < 300) {
    const Eigen::Vector3d x(u(rng), u(rng), u(rng));
    const auto a = camera.ImgFromCam(cam1_from_world * x);
    const auto b = camera.ImgFromCam(cam2_from_world * x);
    if (!a || !b || !camera.InImage(*a) || !camera.InImage(*b)) continue;
    p1.emplace_back(a->x() + n(rng), a->y() + n(rng));
    p2.emplace_back(b->x() + n(rng), b->y() + n(rng));
  }
  const cv::Mat f = cv::findFundamentalMat(p1, p2, cv::FM_8POINT);
  Eigen::Matrix3d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = f.at<double>(r, c);
  }
  return out;
}

// A camera about 6 units from the origin, looking at a point near (not at) the origin, so
// that optical axes do not meet (the generic, non-degenerate case).
Rigid3d GeneralCamera(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d centre = Eigen::Vector3d(u(rng), u(rng) * 0.6, -1.0).normalized() * 6.0;
  const Eigen::Vector3d target(u(rng) * 0.8, u(rng) * 0.8, u(rng) * 0.8);
  return Rigid3d::LookAt(centre, target, Eigen::Vector3d(0, -1, 0));
}

TEST(EssentialCost, ZeroAtTheTrueFocal) {
  std::mt19937 rng(1);
  const Rigid3d a = GeneralCamera(rng), b = GeneralCamera(rng);
  const Eigen::Matrix3d f = NoisyFundamental(a, b, 0.0, rng);
  const double cx = (kWidth - 1) / 2.0, cy = (kHeight - 1) / 2.0;
  EXPECT_LT(EssentialCost(f, kFocal, cx, cy), 1e-6);
  EXPECT_GT(EssentialCost(f, 0.7 * kFocal, cx, cy), 1e-3);
}

TEST(EstimateFocalFromFundamental, RecoversFocalWithoutNoise) {
  std::mt19937 rng(2);
  const Rigid3d a = GeneralCamera(rng), b = GeneralCamera(rng);
  const auto estimate =
      EstimateFocalFromFundamental(NoisyFundamental(a, b, 0.0, rng), (kWidth - 1) / 2.0,
                                   (kHeight - 1) / 2.0, DefaultFocalRange(kWidth, kHeight));
  ASSERT_TRUE(estimate.has_value());
  EXPECT_NEAR(estimate->focal, kFocal, kFocal * 1e-4);
  EXPECT_GT(estimate->sharpness, 0.01);
}

TEST(EstimateSharedFocal, WithinOnePercentAtHalfPixelNoise) {
  std::mt19937 rng(3);
  std::vector<Rigid3d> cameras;
  for (int i = 0; i < 8; ++i) cameras.push_back(GeneralCamera(rng));
  std::vector<Eigen::Matrix3d> fundamentals;
  for (int i = 0; i < 8; ++i) {
    for (int j = i + 1; j < 8; ++j) {
      fundamentals.push_back(NoisyFundamental(cameras[i], cameras[j], 0.5, rng));
    }
  }
  auto estimate = EstimateSharedFocal(fundamentals, (kWidth - 1) / 2.0, (kHeight - 1) / 2.0,
                                      DefaultFocalRange(kWidth, kHeight));
  ASSERT_TRUE(estimate.ok()) << estimate.status();
  EXPECT_NEAR(estimate->focal, kFocal, 0.01 * kFocal);
  EXPECT_EQ(estimate->num_pairs, 28);
  EXPECT_GE(estimate->num_agreeing, 10);
}

TEST(EstimateSharedFocal, OutlierPairsDoNotMoveTheMode) {
  std::mt19937 rng(4);
  std::vector<Rigid3d> cameras;
  for (int i = 0; i < 6; ++i) cameras.push_back(GeneralCamera(rng));
  std::vector<Eigen::Matrix3d> fundamentals;
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      fundamentals.push_back(NoisyFundamental(cameras[i], cameras[j], 0.5, rng));
    }
  }
  // A third of the pairs are garbage: random rank-2 matrices.
  std::normal_distribution<double> n;
  for (int k = 0; k < 7; ++k) {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) m(r, c) = n(rng) * (r == 2 || c == 2 ? 1.0 : 1e-6);
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Vector3d s = svd.singularValues();
    s(2) = 0;
    fundamentals.push_back(svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose());
  }
  auto estimate = EstimateSharedFocal(fundamentals, (kWidth - 1) / 2.0, (kHeight - 1) / 2.0,
                                      DefaultFocalRange(kWidth, kHeight));
  ASSERT_TRUE(estimate.ok()) << estimate.status();
  EXPECT_NEAR(estimate->focal, kFocal, 0.01 * kFocal);
}

TEST(EstimateSharedFocal, AxesMeetingAtOnePointIsDegenerate) {
  // Every camera looks exactly at the origin from a ring: each pair's optical axes meet, the
  // critical configuration in which F says nothing about f (Newsam et al. 1996).
  std::mt19937 rng(5);
  std::vector<Rigid3d> cameras;
  for (int i = 0; i < 6; ++i) {
    const double angle = i * 0.5;
    cameras.push_back(
        Rigid3d::LookAt(Eigen::Vector3d(6 * std::sin(angle), -1.0, -6 * std::cos(angle)),
                        Eigen::Vector3d::Zero(), Eigen::Vector3d(0, -1, 0)));
  }
  std::vector<Eigen::Matrix3d> fundamentals;
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      fundamentals.push_back(NoisyFundamental(cameras[i], cameras[j], 0.0, rng));
    }
  }
  const double cx = (kWidth - 1) / 2.0, cy = (kHeight - 1) / 2.0;
  // The cost is (nearly) zero for any focal: the valley is flat.
  EXPECT_LT(EssentialCost(fundamentals[0], 0.6 * kFocal, cx, cy), 1e-3);
  EXPECT_LT(EssentialCost(fundamentals[0], 1.8 * kFocal, cx, cy), 1e-3);
  auto estimate = EstimateSharedFocal(fundamentals, cx, cy, DefaultFocalRange(kWidth, kHeight));
  EXPECT_FALSE(estimate.ok()) << "focal " << estimate->focal;
  EXPECT_EQ(estimate.status().code(), StatusCode::kDegenerate);
}

TEST(SharedFocalOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(SharedFocalOptions().Check(&error)) << error;
}

}  // namespace
}  // namespace reconduit
