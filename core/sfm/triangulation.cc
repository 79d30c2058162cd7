#include "core/sfm/triangulation.h"

#include "core/util/logging.h"

#include <Eigen/SVD>

#include <cmath>

namespace reconduit {

std::optional<Eigen::Vector3d> TriangulatePoint(const std::vector<Rigid3d>& cams_from_world,
                                                const std::vector<Eigen::Vector2d>& points) {
  THROW_CHECK_EQ(cams_from_world.size(), points.size());
  THROW_CHECK_GE(points.size(), 2u);
  Eigen::MatrixXd a(2 * points.size(), 4);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Matrix3x4d p = cams_from_world[i].ToMatrix();
    a.row(2 * i) = points[i].x() * p.row(2) - p.row(0);
    a.row(2 * i + 1) = points[i].y() * p.row(2) - p.row(1);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d x = svd.matrixV().col(3);
  // A rank-deficient system (fewer than 3 independent rows) has no unique answer.
  const Eigen::VectorXd s = svd.singularValues();
  if (s(2) <= 1e-12 * s(0)) return std::nullopt;
  if (std::abs(x(3)) <= 1e-12 * x.head<3>().norm()) return std::nullopt;
  return Eigen::Vector3d(x.head<3>() / x(3));
}

double TriangulationAngleDeg(const Eigen::Vector3d& center1,
                             const Eigen::Vector3d& center2,
                             const Eigen::Vector3d& point) {
  const Eigen::Vector3d ray1 = point - center1;
  const Eigen::Vector3d ray2 = point - center2;
  const double n = ray1.norm() * ray2.norm();
  if (n == 0.0) return 0.0;
  return std::acos(std::clamp(ray1.dot(ray2) / n, -1.0, 1.0)) * 180.0 / M_PI;
}

bool HasPositiveDepth(const Rigid3d& cam_from_world, const Eigen::Vector3d& point) {
  return (cam_from_world * point).z() > std::numeric_limits<double>::epsilon();
}

}  // namespace reconduit
