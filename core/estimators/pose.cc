#include "core/estimators/pose.h"

#include "core/estimators/solvers/absolute_pose.h"
#include "core/optim/loransac.h"
#include "core/optim/support_measurement.h"
#include "core/util/logging.h"

#include <cmath>
#include <sstream>

namespace reconduit {

bool AbsolutePoseOptions::Check(std::string* error) const {
  std::string ransac_error;
  if (!ransac.Check(&ransac_error)) {
    if (error != nullptr) *error = "AbsolutePoseOptions.ransac: " + ransac_error;
    return false;
  }
  if (min_num_inliers < PnPNonMinimalEstimator::kMinNumSamples) {
    if (error != nullptr) {
      *error = "AbsolutePoseOptions: min_num_inliers must be >= " +
               std::to_string(PnPNonMinimalEstimator::kMinNumSamples) + ", got " +
               std::to_string(min_num_inliers);
    }
    return false;
  }
  if (error != nullptr) error->clear();
  return true;
}

AbsolutePoseReport EstimateAbsolutePose(const Camera& camera,
                                        const std::vector<Eigen::Vector2d>& points2D,
                                        const std::vector<Eigen::Vector3d>& points3D_in_world,
                                        const AbsolutePoseOptions& options,
                                        const CancelToken* cancel) {
  THROW_CHECK_EQ(points2D.size(), points3D_in_world.size());
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK(camera.Check(&error)) << error;

  AbsolutePoseReport report;
  // Undistort and remove K; keep the index of every usable correspondence.
  std::vector<Eigen::Vector2d> normalized;
  std::vector<Eigen::Vector3d> points3D;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < points2D.size(); ++i) {
    const auto ray = camera.CamFromImg(points2D[i]);
    if (!ray || !points3D_in_world[i].allFinite()) continue;
    normalized.push_back(ray->hnormalized());
    points3D.push_back(points3D_in_world[i]);
    index.push_back(i);
  }

  RANSACOptions ransac_options = options.ransac;
  ransac_options.max_error = options.ransac.max_error / camera.focal;
  const auto ransac_report =
      LORANSAC<P3PEstimator, PnPNonMinimalEstimator, MEstimatorSupportMeasurer>(ransac_options)
          .Estimate(normalized, points3D, cancel);
  report.num_trials = ransac_report.num_trials;
  if (ransac_report.canceled) {
    report.canceled = true;
    report.message = "canceled";
    return report;
  }
  if (!ransac_report.success) {
    report.message = ransac_report.message;
    return report;
  }
  if (ransac_report.support.num_inliers < static_cast<std::size_t>(options.min_num_inliers)) {
    std::ostringstream s;
    s << "too few inliers: " << ransac_report.support.num_inliers << " (need "
      << options.min_num_inliers << ")";
    report.message = s.str();
    return report;
  }
  const Matrix3x4d& P = ransac_report.model;
  report.cam_from_world = Rigid3d(Eigen::Matrix3d(P.leftCols<3>()), Eigen::Vector3d(P.col(3)));
  report.inlier_mask.assign(points2D.size(), 0);
  for (std::size_t k = 0; k < index.size(); ++k) {
    report.inlier_mask[index[k]] = ransac_report.inlier_mask[k];
  }
  report.num_inliers = ransac_report.support.num_inliers;
  report.success = true;
  report.message.clear();
  return report;
}

}  // namespace reconduit
