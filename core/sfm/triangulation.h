// Triangulation of scene points from calibrated views.
//
// Points are triangulated from normalised image coordinates (undistorted, K removed) with the
// linear DLT method of Hartley & Zisserman (§12.2), which minimises an algebraic error; the
// mapper then keeps a point only if its reprojection errors, in pixels, and its triangulation
// angle pass the thresholds, and bundle adjustment refines it. The angle matters more than
// the algebraic optimum: points seen under a small angle have poorly determined depth.
#ifndef RECONDUIT_CORE_SFM_TRIANGULATION_H_
#define RECONDUIT_CORE_SFM_TRIANGULATION_H_

#include "core/geometry/rigid3.h"

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace reconduit {

// The point seen at normalised coordinates `points[i]` by cameras `cams_from_world[i]`
// (at least 2). nullopt when the system is degenerate (e.g. identical centres) or the point
// is at infinity.
std::optional<Eigen::Vector3d> TriangulatePoint(const std::vector<Rigid3d>& cams_from_world,
                                                const std::vector<Eigen::Vector2d>& points);

// Angle in degrees between the rays from two camera centres to a point.
double TriangulationAngleDeg(const Eigen::Vector3d& center1,
                             const Eigen::Vector3d& center2,
                             const Eigen::Vector3d& point);

// True when the point is in front of the camera (positive depth).
bool HasPositiveDepth(const Rigid3d& cam_from_world, const Eigen::Vector3d& point);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_TRIANGULATION_H_
