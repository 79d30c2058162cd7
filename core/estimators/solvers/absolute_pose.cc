#include "core/estimators/solvers/absolute_pose.h"

#include "core/util/logging.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <limits>

namespace reconduit {
namespace {

void ToCv(const std::vector<Eigen::Vector2d>& points2D,
          const std::vector<Eigen::Vector3d>& points3D,
          std::vector<cv::Point2d>* image_points,
          std::vector<cv::Point3d>* object_points) {
  image_points->clear();
  object_points->clear();
  for (const auto& p : points2D) image_points->emplace_back(p.x(), p.y());
  for (const auto& p : points3D) object_points->emplace_back(p.x(), p.y(), p.z());
}

// [R | t] from OpenCV's Rodrigues vector and translation; false when not finite.
bool FromCv(const cv::Mat& rvec, const cv::Mat& tvec, Matrix3x4d* cam_from_world) {
  cv::Mat R_cv;
  cv::Rodrigues(rvec, R_cv);
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  cv::cv2eigen(R_cv, R);
  cv::Mat tvec64;
  tvec.convertTo(tvec64, CV_64F);
  t << tvec64.at<double>(0), tvec64.at<double>(1), tvec64.at<double>(2);
  if (!R.allFinite() || !t.allFinite()) return false;
  cam_from_world->leftCols<3>() = R;
  cam_from_world->col(3) = t;
  return true;
}

void ToRvecTvec(const Matrix3x4d& cam_from_world, cv::Mat* rvec, cv::Mat* tvec) {
  cv::Mat R_cv;
  const Eigen::Matrix3d R = cam_from_world.leftCols<3>();
  cv::eigen2cv(R, R_cv);
  cv::Rodrigues(R_cv, *rvec);
  *tvec =
      (cv::Mat_<double>(3, 1) << cam_from_world(0, 3), cam_from_world(1, 3), cam_from_world(2, 3));
}

void ReprojectionResiduals(const std::vector<Eigen::Vector2d>& points2D,
                           const std::vector<Eigen::Vector3d>& points3D,
                           const Matrix3x4d& cam_from_world,
                           std::vector<double>* residuals) {
  THROW_CHECK_EQ(points2D.size(), points3D.size());
  THROW_CHECK_NOTNULL(residuals);
  residuals->resize(points2D.size());
  for (std::size_t i = 0; i < points2D.size(); ++i) {
    const Eigen::Vector3d x = cam_from_world * points3D[i].homogeneous();
    (*residuals)[i] = x.z() > std::numeric_limits<double>::epsilon()
                          ? (x.hnormalized() - points2D[i]).squaredNorm()
                          : std::numeric_limits<double>::max();
  }
}

}  // namespace

void P3PEstimator::Estimate(const std::vector<X_t>& points2D,
                            const std::vector<Y_t>& points3D,
                            std::vector<M_t>* models) {
  THROW_CHECK_EQ(points2D.size(), 3);
  THROW_CHECK_EQ(points3D.size(), 3);
  THROW_CHECK_NOTNULL(models);
  models->clear();
  // Collinear or coincident 3-D points: infinitely many poses; OpenCV's answer is noise.
  const Eigen::Vector3d a = points3D[1] - points3D[0], b = points3D[2] - points3D[0];
  if (!(a.cross(b).norm() > 1e-12 * a.norm() * b.norm()) || !a.allFinite() || !b.allFinite()) {
    return;
  }
  std::vector<cv::Point2d> image_points;
  std::vector<cv::Point3d> object_points;
  ToCv(points2D, points3D, &image_points, &object_points);
  std::vector<cv::Mat> rvecs, tvecs;
  int num_solutions = 0;
  try {
    num_solutions = cv::solveP3P(object_points, image_points, cv::Mat::eye(3, 3, CV_64F), cv::Mat(),
                                 rvecs, tvecs, cv::SOLVEPNP_AP3P);
  } catch (const cv::Exception&) {
    return;  // OpenCV asserts on some degenerate inputs; a degenerate sample has no model.
  }
  for (int i = 0; i < num_solutions; ++i) {
    M_t model;
    if (FromCv(rvecs[i], tvecs[i], &model)) models->push_back(model);
  }
}

void P3PEstimator::Residuals(const std::vector<X_t>& points2D,
                             const std::vector<Y_t>& points3D,
                             const M_t& cam_from_world,
                             std::vector<double>* residuals) {
  ReprojectionResiduals(points2D, points3D, cam_from_world, residuals);
}

void PnPNonMinimalEstimator::Estimate(const std::vector<X_t>& points2D,
                                      const std::vector<Y_t>& points3D,
                                      std::vector<M_t>* models) {
  THROW_CHECK_EQ(points2D.size(), points3D.size());
  THROW_CHECK_GE(points2D.size(), kMinNumSamples);
  THROW_CHECK_NOTNULL(models);
  models->clear();
  std::vector<cv::Point2d> image_points;
  std::vector<cv::Point3d> object_points;
  ToCv(points2D, points3D, &image_points, &object_points);
  cv::Mat rvec, tvec;
  try {
    if (!cv::solvePnP(object_points, image_points, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec,
                      tvec, /*useExtrinsicGuess=*/false, cv::SOLVEPNP_SQPNP)) {
      return;
    }
  } catch (const cv::Exception&) {
    return;
  }
  M_t model;
  if (FromCv(rvec, tvec, &model)) models->push_back(model);
}

void PnPNonMinimalEstimator::Residuals(const std::vector<X_t>& points2D,
                                       const std::vector<Y_t>& points3D,
                                       const M_t& cam_from_world,
                                       std::vector<double>* residuals) {
  ReprojectionResiduals(points2D, points3D, cam_from_world, residuals);
}

void PnPNonMinimalEstimator::Refine(const std::vector<X_t>& points2D,
                                    const std::vector<Y_t>& points3D,
                                    M_t* cam_from_world) {
  THROW_CHECK_EQ(points2D.size(), points3D.size());
  THROW_CHECK_NOTNULL(cam_from_world);
  if (points2D.size() < 3) return;
  std::vector<cv::Point2d> image_points;
  std::vector<cv::Point3d> object_points;
  ToCv(points2D, points3D, &image_points, &object_points);
  cv::Mat rvec, tvec;
  ToRvecTvec(*cam_from_world, &rvec, &tvec);
  try {
    cv::solvePnPRefineLM(object_points, image_points, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec,
                         tvec);
  } catch (const cv::Exception&) {
    return;
  }
  M_t refined;
  if (FromCv(rvec, tvec, &refined)) *cam_from_world = refined;
}

}  // namespace reconduit
