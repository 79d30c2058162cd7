#include "core/scene/camera_layouts.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace reconduit {
namespace {

// Azimuth in degrees of a centre around `target`, in (-180, 180].
double AzimuthDeg(const Eigen::Vector3d& center, const Eigen::Vector3d& target) {
  return std::atan2(center.y() - target.y(), center.x() - target.x()) * 180.0 / M_PI;
}

void ExpectLooksAt(const Rigid3d& cam_from_world, const Eigen::Vector3d& target) {
  const Eigen::Vector3d target_in_cam = cam_from_world * target;
  EXPECT_GT(target_in_cam.z(), 0.0);
  EXPECT_LT(target_in_cam.head<2>().norm(), 1e-12);
  // Image up (-y) is towards world up.
  EXPECT_LT((cam_from_world.rotation * kSyntheticWorldUp).y(), 0.0);
}

TEST(CamerasOnArc, FullRingIsEvenlySpaced) {
  const Eigen::Vector3d target(1.0, -2.0, 0.5);
  const std::vector<Rigid3d> poses = CamerasOnArc(6, target, 4.0, 1.5);
  ASSERT_EQ(poses.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d center = poses[i].CenterInWorld();
    EXPECT_NEAR((center - target).head<2>().norm(), 4.0, 1e-12);
    EXPECT_NEAR(center.z(), target.z() + 1.5, 1e-12);
    EXPECT_NEAR(std::remainder(AzimuthDeg(center, target) - 60.0 * i, 360.0), 0.0, 1e-9);
    ExpectLooksAt(poses[i], target);
  }
}

TEST(CamerasOnArc, PartialArcHasCamerasAtBothEnds) {
  const Eigen::Vector3d target = Eigen::Vector3d::Zero();
  const std::vector<Rigid3d> poses = CamerasOnArc(5, target, 3.0, 0.0, 80.0, 30.0);
  ASSERT_EQ(poses.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(AzimuthDeg(poses[i].CenterInWorld(), target), 30.0 + 20.0 * i, 1e-9);
    ExpectLooksAt(poses[i], target);
  }
  // A single camera on an arc sits in its middle.
  const std::vector<Rigid3d> single = CamerasOnArc(1, target, 3.0, 1.0, 80.0, 30.0);
  EXPECT_NEAR(AzimuthDeg(single[0].CenterInWorld(), target), 70.0, 1e-9);
}

TEST(CamerasOnArc, RejectsBadArguments) {
  const Eigen::Vector3d target = Eigen::Vector3d::Zero();
  EXPECT_THROW(CamerasOnArc(0, target, 3.0, 1.0), CheckError);
  EXPECT_THROW(CamerasOnArc(3, target, 0.0, 1.0), CheckError);
  EXPECT_THROW(CamerasOnArc(3, target, 3.0, 1.0, 0.0), CheckError);
  EXPECT_THROW(CamerasOnArc(3, target, 3.0, 1.0, 400.0), CheckError);
}

TEST(CamerasOnLine, EvenlySpacedBetweenEndsLookingAtTarget) {
  const Eigen::Vector3d target(0.0, 0.0, 1.0);
  const Eigen::Vector3d first(-2.0, -5.0, 2.0), last(2.0, -5.0, 3.0);
  const std::vector<Rigid3d> poses = CamerasOnLine(5, target, first, last);
  ASSERT_EQ(poses.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_LT((poses[i].CenterInWorld() - (first + 0.25 * i * (last - first))).norm(), 1e-12);
    ExpectLooksAt(poses[i], target);
  }
  const std::vector<Rigid3d> single = CamerasOnLine(1, target, first, last);
  EXPECT_LT((single[0].CenterInWorld() - 0.5 * (first + last)).norm(), 1e-12);
  EXPECT_THROW(CamerasOnLine(0, target, first, last), CheckError);
  EXPECT_THROW(CamerasOnLine(2, first, first, last), CheckError);  // A centre on the target.
}

}  // namespace
}  // namespace reconduit
