#include "core/scene/camera_layouts.h"

#include "core/util/logging.h"

#include <cmath>

namespace reconduit {

std::vector<Rigid3d> CamerasOnArc(int num_cameras,
                                  const Eigen::Vector3d& target,
                                  double radius,
                                  double height,
                                  double arc_deg,
                                  double start_deg) {
  THROW_CHECK_GE(num_cameras, 1);
  THROW_CHECK_GT(radius, 0.0);
  THROW_CHECK(arc_deg > 0.0 && arc_deg <= 360.0) << "arc_deg = " << arc_deg;
  // A full ring must not put the last camera on top of the first.
  const bool full_ring = arc_deg == 360.0;
  const double step_deg =
      full_ring ? arc_deg / num_cameras : (num_cameras > 1 ? arc_deg / (num_cameras - 1) : 0.0);
  const double first_deg = (!full_ring && num_cameras == 1) ? start_deg + 0.5 * arc_deg : start_deg;
  std::vector<Rigid3d> cams_from_world;
  cams_from_world.reserve(num_cameras);
  for (int i = 0; i < num_cameras; ++i) {
    const double azimuth = (first_deg + i * step_deg) * M_PI / 180.0;
    const Eigen::Vector3d center =
        target + Eigen::Vector3d(radius * std::cos(azimuth), radius * std::sin(azimuth), height);
    cams_from_world.push_back(Rigid3d::LookAt(center, target, kSyntheticWorldUp));
  }
  return cams_from_world;
}

std::vector<Rigid3d> CamerasOnLine(int num_cameras,
                                   const Eigen::Vector3d& target,
                                   const Eigen::Vector3d& first_center,
                                   const Eigen::Vector3d& last_center) {
  THROW_CHECK_GE(num_cameras, 1);
  std::vector<Rigid3d> cams_from_world;
  cams_from_world.reserve(num_cameras);
  for (int i = 0; i < num_cameras; ++i) {
    const double t = num_cameras > 1 ? static_cast<double>(i) / (num_cameras - 1) : 0.5;
    const Eigen::Vector3d center = first_center + t * (last_center - first_center);
    cams_from_world.push_back(Rigid3d::LookAt(center, target, kSyntheticWorldUp));
  }
  return cams_from_world;
}

}  // namespace reconduit
