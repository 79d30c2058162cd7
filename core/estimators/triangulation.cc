#include "core/estimators/triangulation.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <cmath>

namespace reconduit {

std::optional<Eigen::Vector3d> TriangulatePoint(const Matrix3x4d& cam1_from_world,
                                                const Matrix3x4d& cam2_from_world,
                                                const Eigen::Vector2d& point1,
                                                const Eigen::Vector2d& point2) {
  Eigen::Matrix4d A;
  A.row(0) = point1.x() * cam1_from_world.row(2) - cam1_from_world.row(0);
  A.row(1) = point1.y() * cam1_from_world.row(2) - cam1_from_world.row(1);
  A.row(2) = point2.x() * cam2_from_world.row(2) - cam2_from_world.row(0);
  A.row(3) = point2.y() * cam2_from_world.row(2) - cam2_from_world.row(1);
  if (!A.allFinite()) return std::nullopt;
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  // |w| relative to the point's extent: below this the point is at infinity in practice.
  if (!(std::abs(X(3)) > 1e-12 * X.head<3>().norm())) return std::nullopt;
  const Eigen::Vector3d point = X.hnormalized();
  if (!point.allFinite()) return std::nullopt;
  return point;
}

std::optional<Eigen::Vector3d> TriangulateMidPoint(const Rigid3d& cam1_from_world,
                                                   const Rigid3d& cam2_from_world,
                                                   const Eigen::Vector2d& point1,
                                                   const Eigen::Vector2d& point2) {
  const Eigen::Vector3d c1 = cam1_from_world.CenterInWorld();
  const Eigen::Vector3d c2 = cam2_from_world.CenterInWorld();
  const Eigen::Vector3d d1 =
      (cam1_from_world.rotation.inverse() * point1.homogeneous()).normalized();
  const Eigen::Vector3d d2 =
      (cam2_from_world.rotation.inverse() * point2.homogeneous()).normalized();
  // Minimise |c1 + s d1 - (c2 + u d2)|² over s, u: a 2x2 normal system.
  const Eigen::Vector3d b = c2 - c1;
  const double d12 = d1.dot(d2);
  const double denominator = 1.0 - d12 * d12;
  if (!(denominator > 1e-12)) return std::nullopt;  // Parallel rays.
  const double s = (d1.dot(b) - d12 * d2.dot(b)) / denominator;
  const double u = (d12 * d1.dot(b) - d2.dot(b)) / denominator;
  const Eigen::Vector3d point = 0.5 * ((c1 + s * d1) + (c2 + u * d2));
  if (!point.allFinite()) return std::nullopt;
  return point;
}

double CalculateTriangulationAngle(const Eigen::Vector3d& center1_in_world,
                                   const Eigen::Vector3d& center2_in_world,
                                   const Eigen::Vector3d& point3D_in_world) {
  const Eigen::Vector3d ray1 = center1_in_world - point3D_in_world;
  const Eigen::Vector3d ray2 = center2_in_world - point3D_in_world;
  const double norms = ray1.norm() * ray2.norm();
  if (!(norms > 0.0)) return 0.0;
  // atan2 of |cross| and dot is accurate for small angles, unlike acos of the dot product.
  return std::atan2(ray1.cross(ray2).norm(), ray1.dot(ray2));
}

bool HasPositiveDepth(const Rigid3d& cam_from_world, const Eigen::Vector3d& point3D_in_world) {
  return (cam_from_world * point3D_in_world).z() > 0.0;
}

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

}  // namespace reconduit
