// Test-only: small synthetic two-view scenes with known geometry, for the estimator tests.
// (core/scene/synthetic.h is the general generator; this one stays local to core/estimators
// so the estimators do not depend on scene/.)
#ifndef RECONDUIT_CORE_ESTIMATORS_SYNTHETIC_TWO_VIEW_TEST_UTIL_H_
#define RECONDUIT_CORE_ESTIMATORS_SYNTHETIC_TWO_VIEW_TEST_UTIL_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <random>
#include <vector>

namespace reconduit {
namespace testing_util {

enum class SceneKind {
  kGeneral,   // Points in a box 4-8 units deep, camera 2 translated 1 unit sideways.
  kPlanar,    // Points on one tilted plane, same cameras as kGeneral.
  kRotation,  // Points in the box, camera 2 rotated 12 degrees about the same centre.
};

struct TwoViewScene {
  Camera camera = Camera::FromFocal(1000, 800, 900.0);
  Rigid3d cam1_from_world;  // Identity: world = camera 1.
  Rigid3d cam2_from_world;
  std::vector<Eigen::Vector3d> points3D;  // Inliers only, world frame.
  // Observations in pixels; inliers first-come interleaved with outliers (see is_inlier).
  std::vector<Eigen::Vector2d> points1, points2;
  std::vector<char> is_inlier;
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();  // x2^T F x1 = 0, unit norm.
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // x2 ~ H x1 (planar and rotation scenes).
};

inline Eigen::Matrix3d CrossMatrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Inliers are projected with Gaussian pixel noise `noise_px` (per coordinate); outliers are
// independent uniform pixels in both images. Inliers and outliers alternate while both last.
inline TwoViewScene MakeTwoViewScene(
    SceneKind kind, int num_inliers, int num_outliers, double noise_px, unsigned seed) {
  TwoViewScene scene;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px > 0 ? noise_px : 1.0);
  const Camera& cam = scene.camera;

  if (kind == SceneKind::kRotation) {
    scene.cam2_from_world =
        Rigid3d(Eigen::AngleAxisd(12.0 * M_PI / 180.0, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())
                    .toRotationMatrix(),
                Eigen::Vector3d::Zero());
  } else {
    scene.cam2_from_world = Rigid3d::LookAt(
        Eigen::Vector3d(1.0, 0.1, 0.0), Eigen::Vector3d(0.0, 0.0, 6.0), -Eigen::Vector3d::UnitY());
  }
  const Eigen::Matrix3d R = scene.cam2_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d t = scene.cam2_from_world.translation;
  const Eigen::Matrix3d K = cam.K();
  const Eigen::Matrix3d K_inv = K.inverse();
  if (kind != SceneKind::kRotation) {
    scene.F = K_inv.transpose() * CrossMatrix(t) * R * K_inv;
    scene.F /= scene.F.norm();
  }
  // Plane n^T X = d in camera 1 (= world): z = 6 + 0.3 x - 0.2 y.
  const Eigen::Vector3d n = Eigen::Vector3d(-0.3, 0.2, 1.0);
  const double d = 6.0;
  if (kind == SceneKind::kPlanar) {
    scene.H = K * (R + t * n.transpose() / d) * K_inv;
  } else if (kind == SceneKind::kRotation) {
    scene.H = K * R * K_inv;
  }
  if (kind != SceneKind::kGeneral) scene.H /= scene.H.norm();

  std::vector<Eigen::Vector2d> in1, in2;
  while (static_cast<int>(in1.size()) < num_inliers) {
    Eigen::Vector3d X(-2.5 + 5.0 * u01(rng), -2.0 + 4.0 * u01(rng), 4.0 + 4.0 * u01(rng));
    if (kind == SceneKind::kPlanar) X.z() = (d - n.x() * X.x() - n.y() * X.y()) / n.z();
    const auto p1 = cam.ImgFromCam(scene.cam1_from_world * X);
    const auto p2 = cam.ImgFromCam(scene.cam2_from_world * X);
    if (!p1 || !p2 || !cam.InImage(*p1) || !cam.InImage(*p2)) continue;
    Eigen::Vector2d o1 = *p1, o2 = *p2;
    if (noise_px > 0) {
      o1 += Eigen::Vector2d(noise(rng), noise(rng));
      o2 += Eigen::Vector2d(noise(rng), noise(rng));
    }
    scene.points3D.push_back(X);
    in1.push_back(o1);
    in2.push_back(o2);
  }
  const auto random_pixel = [&] {
    return Eigen::Vector2d(u01(rng) * (cam.width - 1), u01(rng) * (cam.height - 1));
  };
  int next_inlier = 0, next_outlier = 0;
  while (next_inlier < num_inliers || next_outlier < num_outliers) {
    const bool take_inlier =
        next_inlier < num_inliers && (next_outlier >= num_outliers || next_inlier <= next_outlier);
    if (take_inlier) {
      scene.points1.push_back(in1[next_inlier]);
      scene.points2.push_back(in2[next_inlier]);
      ++next_inlier;
    } else {
      scene.points1.push_back(random_pixel());
      scene.points2.push_back(random_pixel());
      ++next_outlier;
    }
    scene.is_inlier.push_back(take_inlier ? 1 : 0);
  }
  return scene;
}

// Frobenius distance between two matrices defined up to scale and sign.
inline double DistanceUpToScale(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::Matrix3d an = a / a.norm(), bn = b / b.norm();
  return std::min((an - bn).norm(), (an + bn).norm());
}

}  // namespace testing_util
}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_SYNTHETIC_TWO_VIEW_TEST_UTIL_H_
