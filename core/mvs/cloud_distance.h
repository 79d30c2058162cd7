// Distances from points to a point cloud, for checking a dense cloud against the sparse one.
//
// The consistency figure on real photos, with no true surface to compare with: the
// median distance from the sparse stage's points to the nearest dense point, as a share of
// the scene depth. Only distances up to a radius matter (a median above 1 % of the scene depth
// is a failure whatever its value), so the search is a uniform grid of cells of that radius:
// exact within the radius, +infinity beyond, and no dependency on a k-d tree library.
#ifndef RECONDUIT_CORE_MVS_CLOUD_DISTANCE_H_
#define RECONDUIT_CORE_MVS_CLOUD_DISTANCE_H_

#include <Eigen/Core>

#include <vector>

namespace reconduit {

// For every query, the distance to the nearest point of `cloud` if it is <= radius, otherwise
// +infinity. radius > 0. O((cloud + queries) log cloud).
std::vector<double> NearestDistancesWithin(const std::vector<Eigen::Vector3f>& cloud,
                                           const std::vector<Eigen::Vector3d>& queries,
                                           double radius);

// The median of `values` (+infinity stays +infinity); NaN when empty.
double Median(std::vector<double> values);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_CLOUD_DISTANCE_H_
