// Two-view triangulation and the checks that go with it (angle, depth).
//
// Points are in NORMALISED image coordinates (x/z, y/z in the camera frame: undistorted pixel
// coordinates with K removed, e.g. Camera::CamFromImg(pixel)->hnormalized()); poses are
// `cam_from_world` (core/geometry/rigid3.h). 3-D points are returned in the world frame.
#ifndef RECONDUIT_CORE_ESTIMATORS_TRIANGULATION_H_
#define RECONDUIT_CORE_ESTIMATORS_TRIANGULATION_H_

#include "core/geometry/rigid3.h"

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace reconduit {

// Linear (DLT) triangulation, Hartley & Zisserman 2nd ed. §12.2: the null vector of the 4x4
// system x × (P X) = 0 for both views. Optimal in no sense but exact for exact data and a good
// start for refinement; with projection matrices cam_from_world = [R | t] the residual is
// algebraic in normalised units. nullopt when the solution is at infinity (parallel rays) or
// not finite. Does NOT check that the point is in front of the cameras (see HasPositiveDepth).
std::optional<Eigen::Vector3d> TriangulatePoint(const Matrix3x4d& cam1_from_world,
                                                const Matrix3x4d& cam2_from_world,
                                                const Eigen::Vector2d& point1,
                                                const Eigen::Vector2d& point2);

// Midpoint method (H&Z §12.1; Beardsley et al. 1994): the midpoint of the shortest segment
// between the two viewing rays. nullopt for (near-)parallel rays, where it is undefined.
// The point seen at normalised coordinates `points[i]` by cameras `cams_from_world[i]`, for
// two or more views: the linear DLT of Hartley & Zisserman §12.2 over all views (algebraic
// error). nullopt when the system is rank-deficient (e.g. identical centres) or the point is
// at infinity. Throws CheckError for fewer than 2 views or mismatched sizes.
std::optional<Eigen::Vector3d> TriangulatePoint(const std::vector<Rigid3d>& cams_from_world,
                                                const std::vector<Eigen::Vector2d>& points);

std::optional<Eigen::Vector3d> TriangulateMidPoint(const Rigid3d& cam1_from_world,
                                                   const Rigid3d& cam2_from_world,
                                                   const Eigen::Vector2d& point1,
                                                   const Eigen::Vector2d& point2);

// Angle in RADIANS at `point3D` between the rays to the two camera centres (world frame).
// Small angles mean poorly conditioned depth; COLMAP-style pipelines reject points below
// ~1.5 degrees when initialising. 0 when the point coincides with a centre.
double CalculateTriangulationAngle(const Eigen::Vector3d& center1_in_world,
                                   const Eigen::Vector3d& center2_in_world,
                                   const Eigen::Vector3d& point3D_in_world);

// True when the point is strictly in front of the camera (z > 0 in the camera frame).
bool HasPositiveDepth(const Rigid3d& cam_from_world, const Eigen::Vector3d& point3D_in_world);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_TRIANGULATION_H_
