// Rigid transforms, named by the frames they map between.
//
// A Rigid3d called `b_from_a` maps a point expressed in frame a into frame b:
//   x_in_b = b_from_a.rotation * x_in_a + b_from_a.translation.
// Poses are stored as `cam_from_world` (world-to-camera), as in COLMAP; the camera centre in
// the world is then -R^T t. Composition reads right to left: c_from_a = c_from_b * b_from_a.
#ifndef RECONDUIT_CORE_GEOMETRY_RIGID3_H_
#define RECONDUIT_CORE_GEOMETRY_RIGID3_H_

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <ostream>

namespace reconduit {

using Matrix3x4d = Eigen::Matrix<double, 3, 4>;

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& r, const Eigen::Vector3d& t)
      : rotation(r.normalized()), translation(t) {}
  Rigid3d(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) : Rigid3d(Eigen::Quaterniond(r), t) {}

  // [R | t] as a 3x4 matrix.
  Matrix3x4d ToMatrix() const;
  Rigid3d Inverse() const;

  // For a cam_from_world pose: the camera centre in world coordinates, -R^T t.
  Eigen::Vector3d CenterInWorld() const { return -(rotation.inverse() * translation); }

  // The cam_from_world pose of a camera at `center_in_world` looking at `target_in_world`,
  // with image "up" (-y in the camera) as close as possible to `up_in_world`. The camera
  // looks down +z, x to the right, y down (the computer-vision convention).
  static Rigid3d LookAt(const Eigen::Vector3d& center_in_world,
                        const Eigen::Vector3d& target_in_world,
                        const Eigen::Vector3d& up_in_world = Eigen::Vector3d::UnitY());
};

inline Eigen::Vector3d operator*(const Rigid3d& b_from_a, const Eigen::Vector3d& x_in_a) {
  return b_from_a.rotation * x_in_a + b_from_a.translation;
}

inline Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a) {
  return Rigid3d(c_from_b.rotation * b_from_a.rotation,
                 c_from_b.rotation * b_from_a.translation + c_from_b.translation);
}

// Angle of the rotation between two transforms, in degrees.
double RotationDifferenceDeg(const Rigid3d& a, const Rigid3d& b);

std::ostream& operator<<(std::ostream& os, const Rigid3d& t);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_GEOMETRY_RIGID3_H_
