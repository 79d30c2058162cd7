// Hartley normalisation of image points, used by every linear two-view solver.
//
// Hartley 1997, "In Defense of the Eight-Point Algorithm", PAMI 19(6); Hartley & Zisserman,
// "Multiple View Geometry", 2nd ed., §4.4.4: translate the points so that their centroid is at
// the origin and scale them so that their mean distance from it is sqrt(2). This makes the
// DLT systems well conditioned (and the results independent of the pixel origin and scale).
#ifndef RECONDUIT_CORE_ESTIMATORS_NORMALIZATION_H_
#define RECONDUIT_CORE_ESTIMATORS_NORMALIZATION_H_

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// Normalises `points` (any units, e.g. pixels).
//
// @param points                    At least one point.
// @param normalized_points         Output, same size: T * [p; 1], dehomogenised.
// @param normalized_from_original  Output similarity T (3x3, homogeneous).
// @return false, leaving the outputs unspecified, when the points coincide (mean distance from
//         the centroid below 1e-12 times their magnitude, plus 1e-300) or are not finite; a
//         solver must then return no model.
bool CenterAndNormalizeImagePoints(const std::vector<Eigen::Vector2d>& points,
                                   std::vector<Eigen::Vector2d>* normalized_points,
                                   Eigen::Matrix3d* normalized_from_original);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_NORMALIZATION_H_
