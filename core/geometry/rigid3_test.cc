#include "core/geometry/rigid3.h"

#include "core/geometry/camera.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <vector>

namespace reconduit {
namespace {

Rigid3d RandomRigid(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return Rigid3d(q, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 3.0);
}

Eigen::Vector3d RandomPoint(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uniform(-5.0, 5.0);
  return {uniform(rng), uniform(rng), uniform(rng)};
}

TEST(Rigid3d, DefaultIsIdentity) {
  const Rigid3d identity;
  const Eigen::Vector3d x(1.0, -2.0, 3.0);
  EXPECT_EQ(identity * x, x);
  EXPECT_EQ(identity.ToMatrix(), Matrix3x4d::Identity());
}

TEST(Rigid3d, ConstructorNormalisesRotation) {
  const Rigid3d t(Eigen::Quaterniond(2.0, 0.0, 0.0, 2.0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(t.rotation.norm(), 1.0, 1e-15);
  // 90 degrees about z.
  EXPECT_LT((t * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
}

TEST(Rigid3d, AppliesRotationThenTranslation) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).matrix();
  const Rigid3d b_from_a(r, Eigen::Vector3d(10.0, 0.0, 0.0));
  EXPECT_LT((b_from_a * Eigen::Vector3d(1.0, 0.0, 0.0) - Eigen::Vector3d(10.0, 1.0, 0.0)).norm(),
            1e-15);
}

TEST(Rigid3d, ToMatrixMatchesApplication) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 20; ++i) {
    const Rigid3d t = RandomRigid(rng);
    const Eigen::Vector3d x = RandomPoint(rng);
    EXPECT_LT((t.ToMatrix() * x.homogeneous() - t * x).norm(), 1e-12);
  }
}

TEST(Rigid3d, CompositionReadsRightToLeft) {
  std::mt19937_64 rng(2);
  for (int i = 0; i < 20; ++i) {
    const Rigid3d b_from_a = RandomRigid(rng);
    const Rigid3d c_from_b = RandomRigid(rng);
    const Eigen::Vector3d x_in_a = RandomPoint(rng);
    const Rigid3d c_from_a = c_from_b * b_from_a;
    EXPECT_LT((c_from_a * x_in_a - c_from_b * (b_from_a * x_in_a)).norm(), 1e-12);
    EXPECT_NEAR(c_from_a.rotation.norm(), 1.0, 1e-14);
  }
}

TEST(Rigid3d, CompositionIsAssociative) {
  std::mt19937_64 rng(3);
  const Rigid3d a = RandomRigid(rng), b = RandomRigid(rng), c = RandomRigid(rng);
  const Rigid3d left = (a * b) * c, right = a * (b * c);
  EXPECT_LT(RotationDifferenceDeg(left, right), 1e-6);
  EXPECT_LT((left.translation - right.translation).norm(), 1e-12);
}

TEST(Rigid3d, InverseUndoesTransform) {
  std::mt19937_64 rng(4);
  for (int i = 0; i < 20; ++i) {
    const Rigid3d b_from_a = RandomRigid(rng);
    const Rigid3d a_from_b = b_from_a.Inverse();
    const Eigen::Vector3d x = RandomPoint(rng);
    EXPECT_LT((a_from_b * (b_from_a * x) - x).norm(), 1e-12);
    EXPECT_LT((b_from_a * (a_from_b * x) - x).norm(), 1e-12);
    const Rigid3d identity = b_from_a * a_from_b;
    EXPECT_LT(identity.translation.norm(), 1e-12);
    EXPECT_LT(RotationDifferenceDeg(identity, Rigid3d()), 1e-6);
    // Inverting twice gives back the transform.
    const Rigid3d twice = a_from_b.Inverse();
    EXPECT_LT((twice.ToMatrix() - b_from_a.ToMatrix()).norm(), 1e-12);
  }
}

TEST(Rigid3d, CenterInWorldMapsToCameraOrigin) {
  std::mt19937_64 rng(5);
  for (int i = 0; i < 20; ++i) {
    const Rigid3d cam_from_world = RandomRigid(rng);
    const Eigen::Vector3d center = cam_from_world.CenterInWorld();
    EXPECT_LT((cam_from_world * center).norm(), 1e-12);
    EXPECT_LT((center - cam_from_world.Inverse().translation).norm(), 1e-12);
  }
  // A camera translated to world x = 2 (no rotation) has t = -2 x.
  EXPECT_LT((Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-2, 0, 0)).CenterInWorld() -
             Eigen::Vector3d(2, 0, 0))
                .norm(),
            1e-15);
}

TEST(Rigid3d, RotationDifference) {
  const Rigid3d a;
  const Rigid3d b(
      Eigen::Matrix3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d(1, 1, 0).normalized())),
      Eigen::Vector3d(5, 5, 5));
  EXPECT_NEAR(RotationDifferenceDeg(a, b), 90.0, 1e-9);
  EXPECT_NEAR(RotationDifferenceDeg(b, a), 90.0, 1e-9);
  EXPECT_NEAR(RotationDifferenceDeg(b, b), 0.0, 1e-6);
}

TEST(Rigid3d, LookAtPutsTargetOnOpticalAxisWithImageUpAlongWorldUp) {
  const Camera camera = Camera::FromFocal(640, 480, 500.0);
  std::mt19937_64 rng(6);
  const std::vector<Eigen::Vector3d> ups = {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                                            Eigen::Vector3d(0.3, -1.0, 0.2).normalized()};
  for (const Eigen::Vector3d& up : ups) {
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d center = RandomPoint(rng);
      const Eigen::Vector3d target = RandomPoint(rng);
      const Rigid3d cam_from_world = Rigid3d::LookAt(center, target, up);

      // A proper rotation, and the camera sits at `center`.
      EXPECT_NEAR(cam_from_world.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
      EXPECT_LT((cam_from_world.CenterInWorld() - center).norm(), 1e-12);

      // The target is straight ahead at its distance, so it projects to the principal point.
      const Eigen::Vector3d target_in_cam = cam_from_world * target;
      EXPECT_NEAR(target_in_cam.z(), (target - center).norm(), 1e-12);
      const Eigen::Vector2d pixel = *camera.ImgFromCam(target_in_cam);
      EXPECT_LT((pixel - Eigen::Vector2d(camera.cx, camera.cy)).norm(), 1e-9);

      // World "up" maps to negative image y (up in the image), with no x component.
      const Eigen::Vector3d up_in_cam = cam_from_world.rotation * up;
      const Eigen::Vector3d forward = (target - center).normalized();
      if (std::abs(forward.dot(up)) > 0.99) continue;
      EXPECT_LT(up_in_cam.y(), 0.0);
      EXPECT_NEAR(up_in_cam.x(), 0.0, 1e-12);
      const Eigen::Vector2d above = *camera.ImgFromCam(cam_from_world * (target + 0.1 * up));
      EXPECT_LT(above.y(), camera.cy);
      EXPECT_NEAR(above.x(), camera.cx, 1e-9);
    }
  }
}

TEST(Rigid3d, LookAtImageXPointsRight) {
  // Camera on -z looking at the origin, world y up: in a right-handed world the viewer's
  // right is -x, so a point at -x appears right of the centre.
  const Camera camera = Camera::FromFocal(640, 480, 500.0);
  const Rigid3d cam_from_world =
      Rigid3d::LookAt(Eigen::Vector3d(0, 0, -5), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY());
  const Eigen::Vector2d right = *camera.ImgFromCam(cam_from_world * Eigen::Vector3d(-1, 0, 0));
  EXPECT_GT(right.x(), camera.cx + 50.0);
  EXPECT_NEAR(right.y(), camera.cy, 1e-9);
  const Eigen::Vector2d up = *camera.ImgFromCam(cam_from_world * Eigen::Vector3d(0, 1, 0));
  EXPECT_LT(up.y(), camera.cy - 50.0);
}

TEST(Rigid3d, LookAtAlongUpStillGivesValidPose) {
  const Eigen::Vector3d center(1, 5, 2), target(1, -3, 2);  // Looking straight down -y.
  const Rigid3d cam_from_world = Rigid3d::LookAt(center, target, Eigen::Vector3d::UnitY());
  EXPECT_NEAR(cam_from_world.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
  const Eigen::Vector3d target_in_cam = cam_from_world * target;
  EXPECT_NEAR(target_in_cam.z(), 8.0, 1e-12);
  EXPECT_NEAR(target_in_cam.head<2>().norm(), 0.0, 1e-12);
}

TEST(Rigid3d, LookAtRejectsCoincidentCenterAndTarget) {
  EXPECT_THROW(Rigid3d::LookAt(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 2, 3)), CheckError);
}

TEST(Rigid3d, Streams) {
  std::ostringstream os;
  os << Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(os.str(), "Rigid3d(q=[1, 0, 0, 0], t=[1 2 3])");
}

}  // namespace
}  // namespace reconduit
