// Camera placements for synthetic scenes: cameras on a ring, an arc or a line, all looking at
// a target.
//
// World frame of every synthetic scene in core/scene: right-handed, metres, +z up (the ground
// is z = 0). Poses are cam_from_world (see core/geometry/rigid3.h); cameras look down their
// +z axis with image "up" (-y) towards world +z.
#ifndef RECONDUIT_CORE_SCENE_CAMERA_LAYOUTS_H_
#define RECONDUIT_CORE_SCENE_CAMERA_LAYOUTS_H_

#include "core/geometry/rigid3.h"

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// The "up" direction of synthetic worlds.
inline const Eigen::Vector3d kSyntheticWorldUp = Eigen::Vector3d::UnitZ();

// `num_cameras` cam_from_world poses with centres on a horizontal circle of `radius` metres
// around `target`, `height` metres above it, all looking at `target`. The centres are spread
// evenly over an arc of `arc_deg` degrees starting at azimuth `start_deg` (0 = +x, 90 = +y):
// a full ring (arc_deg = 360) spaces them arc_deg / num_cameras apart; a partial arc puts the
// first and last camera at its ends. Throws CheckError for num_cameras < 1, radius <= 0 or
// arc_deg outside (0, 360].
std::vector<Rigid3d> CamerasOnArc(int num_cameras,
                                  const Eigen::Vector3d& target,
                                  double radius,
                                  double height,
                                  double arc_deg = 360.0,
                                  double start_deg = 0.0);

// `num_cameras` poses with centres evenly spaced on the segment from `first_center` to
// `last_center` (the first at `first_center`, the last at `last_center`; a single camera sits
// at the middle), all looking at `target`. Throws CheckError for num_cameras < 1 or if a centre
// equals `target`.
std::vector<Rigid3d> CamerasOnLine(int num_cameras,
                                   const Eigen::Vector3d& target,
                                   const Eigen::Vector3d& first_center,
                                   const Eigen::Vector3d& last_center);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_CAMERA_LAYOUTS_H_
