#include "core/geometry/rigid3.h"

#include "core/util/logging.h"

#include <cmath>

namespace reconduit {

Matrix3x4d Rigid3d::ToMatrix() const {
  Matrix3x4d m;
  m.leftCols<3>() = rotation.toRotationMatrix();
  m.col(3) = translation;
  return m;
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inv = rotation.inverse();
  return Rigid3d(inv, -(inv * translation));
}

Rigid3d Rigid3d::LookAt(const Eigen::Vector3d& center_in_world,
                        const Eigen::Vector3d& target_in_world,
                        const Eigen::Vector3d& up_in_world) {
  const Eigen::Vector3d forward = target_in_world - center_in_world;
  THROW_CHECK_GT(forward.norm(), 0.0) << "camera centre and target coincide";
  const Eigen::Vector3d z = forward.normalized();
  Eigen::Vector3d x = z.cross(up_in_world);  // Camera x points right when y points down.
  if (x.norm() < 1e-9) {
    // Looking straight along `up`: any perpendicular will do.
    x = z.unitOrthogonal();
  }
  x.normalize();
  // Image y points down, i.e. away from "up".
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_cam_rotation;
  world_from_cam_rotation.col(0) = x;
  world_from_cam_rotation.col(1) = y;
  world_from_cam_rotation.col(2) = z;
  const Eigen::Matrix3d r = world_from_cam_rotation.transpose();
  return Rigid3d(r, -r * center_in_world);
}

double RotationDifferenceDeg(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.angularDistance(b.rotation) * 180.0 / M_PI;
}

std::ostream& operator<<(std::ostream& os, const Rigid3d& t) {
  const Eigen::Quaterniond& q = t.rotation;
  return os << "Rigid3d(q=[" << q.w() << ", " << q.x() << ", " << q.y() << ", " << q.z() << "], t=["
            << t.translation.transpose() << "])";
}

}  // namespace reconduit
