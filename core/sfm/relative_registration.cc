#include "core/sfm/relative_registration.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace reconduit {
namespace {

constexpr std::uint64_t kSeed = 0x2545f491;

double Degrees(double radians) { return radians * 180.0 / M_PI; }

// The new photo's rotation and its centre's ray (origin, unit direction) in world coordinates.
struct Ray {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

Ray RayOf(const NeighbourPose& n) {
  const Eigen::Matrix3d r_rel = n.relative.new_from_registered.rotation.toRotationMatrix();
  Ray ray;
  ray.rotation = r_rel * n.registered_cam_from_world.rotation.toRotationMatrix();
  ray.origin = n.registered_cam_from_world.CenterInWorld();
  // C_new = C_registered - s R_newᵀ t_rel.
  ray.direction = -(ray.rotation.transpose() * n.relative.new_from_registered.translation);
  ray.direction.normalize();
  return ray;
}

// The rotation nearest (Frobenius) to the sum of `rotations`: their chordal mean.
Eigen::Matrix3d ChordalMean(const std::vector<Eigen::Matrix3d>& rotations) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (const Eigen::Matrix3d& r : rotations) sum += r;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The Sampson distances (normalised units) of the correspondences under E = [t]x R.
Eigen::VectorXd SampsonResiduals(const Eigen::Matrix3d& r,
                                 const Eigen::Vector3d& t,
                                 const std::vector<Eigen::Vector3d>& x1,
                                 const std::vector<Eigen::Vector3d>& x2) {
  const Eigen::Matrix3d e = Skew(t) * r;
  Eigen::VectorXd residuals(x1.size());
  for (std::size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector3d l2 = e * x1[i];
    const Eigen::Vector3d l1 = e.transpose() * x2[i];
    const double denominator = l2.head<2>().squaredNorm() + l1.head<2>().squaredNorm();
    residuals[i] = x2[i].dot(l2) / std::sqrt(std::max(denominator, 1e-30));
  }
  return residuals;
}

// Cauchy loss of the Sampson distances at scale `scale`: sum of log(1 + (r / scale)^2); the
// sum of squares for an infinite scale.
double RobustCost(const Eigen::VectorXd& residuals, double scale) {
  if (std::isinf(scale)) return residuals.squaredNorm();
  return (residuals.array() / scale).square().log1p().sum();
}

// Depths of a correspondence's point along both rays (x2 d2 = R x1 d1 + t, least squares).
Eigen::Vector2d Depths(const Eigen::Matrix3d& r,
                       const Eigen::Vector3d& t,
                       const Eigen::Vector3d& x1,
                       const Eigen::Vector3d& x2) {
  Eigen::Matrix<double, 3, 2> a;
  a.col(0) = r * x1;
  a.col(1) = -x2;
  return a.colPivHouseholderQr().solve(-t);
}

}  // namespace

std::vector<double> EpipolarDistances(const Rigid3d& second_from_first,
                                      const std::vector<Eigen::Vector2d>& first,
                                      const std::vector<Eigen::Vector2d>& second) {
  std::vector<Eigen::Vector3d> x1, x2;
  for (const Eigen::Vector2d& x : first) x1.push_back(x.homogeneous());
  for (const Eigen::Vector2d& x : second) x2.push_back(x.homogeneous());
  const Eigen::VectorXd residuals =
      SampsonResiduals(second_from_first.rotation.toRotationMatrix(),
                       second_from_first.translation.normalized(), x1, x2);
  std::vector<double> distances(residuals.size());
  for (Eigen::Index i = 0; i < residuals.size(); ++i) distances[i] = std::abs(residuals[i]);
  return distances;
}

void RefineRelativePose(const std::vector<Eigen::Vector3d>& x1,
                        const std::vector<Eigen::Vector3d>& x2,
                        double scale,
                        Eigen::Matrix3d* r,
                        Eigen::Vector3d* t) {
  THROW_CHECK_EQ(x1.size(), x2.size());
  THROW_CHECK(scale > 0) << "scale must be positive";
  if (x1.size() < 5) return;
  auto apply = [&](const Eigen::Matrix<double, 5, 1>& d, Eigen::Matrix3d* r_out,
                   Eigen::Vector3d* t_out) {
    const Eigen::Vector3d w = d.head<3>();
    const double angle = w.norm();
    const Eigen::Matrix3d dr = angle > 0 ? Eigen::AngleAxisd(angle, w / angle).toRotationMatrix()
                                         : Eigen::Matrix3d::Identity();
    *r_out = dr * *r;
    Eigen::Vector3d b1 = t->unitOrthogonal();
    Eigen::Vector3d b2 = t->cross(b1).normalized();
    *t_out = (*t + d[3] * b1 + d[4] * b2).normalized();
  };
  t->normalize();
  double lambda = 1e-3;
  Eigen::VectorXd residuals = SampsonResiduals(*r, *t, x1, x2);
  double cost = RobustCost(residuals, scale);
  for (int iteration = 0; iteration < 50; ++iteration) {
    // Iteratively reweighted: the Cauchy weight 1 / (1 + (r / scale)^2) of each residual.
    const Eigen::VectorXd weights =
        std::isinf(scale) ? Eigen::VectorXd::Ones(residuals.size())
                          : Eigen::VectorXd(((residuals.array() / scale).square() + 1.0).inverse());
    Eigen::MatrixXd jacobian(residuals.size(), 5);
    const double h = 1e-7;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> d = Eigen::Matrix<double, 5, 1>::Zero();
      d[k] = h;
      Eigen::Matrix3d rp;
      Eigen::Vector3d tp;
      apply(d, &rp, &tp);
      jacobian.col(k) = (SampsonResiduals(rp, tp, x1, x2) - residuals) / h;
    }
    const Eigen::Matrix<double, 5, 5> jtj = jacobian.transpose() * weights.asDiagonal() * jacobian;
    const Eigen::Matrix<double, 5, 1> jtr = jacobian.transpose() * weights.cwiseProduct(residuals);
    bool improved = false;
    double decrease = 0.0;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      Eigen::Matrix<double, 5, 5> damped = jtj;
      damped.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 5, 1> d = damped.ldlt().solve(-jtr);
      Eigen::Matrix3d rp;
      Eigen::Vector3d tp;
      apply(d, &rp, &tp);
      const Eigen::VectorXd candidate = SampsonResiduals(rp, tp, x1, x2);
      const double candidate_cost = RobustCost(candidate, scale);
      if (d.allFinite() && candidate_cost < cost) {
        decrease = (cost - candidate_cost) / std::max(cost, 1e-300);
        *r = rp;
        *t = tp;
        residuals = candidate;
        cost = candidate_cost;
        lambda = std::max(1e-9, lambda / 10);
        improved = true;
      } else {
        lambda *= 10;
      }
    }
    if (!improved || decrease < 1e-10) break;
  }
}

bool RelativeRegistrationOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (min_pair_inliers < 8) {
    m << "min_pair_inliers must be at least 8, got " << min_pair_inliers;
  } else if (!(max_epipolar_error_px > 0)) {
    m << "max_epipolar_error_px must be positive, got " << max_epipolar_error_px;
  } else if (!(max_scale_angle_deg > 0 && max_scale_angle_deg < 90)) {
    m << "max_scale_angle_deg must be in (0, 90), got " << max_scale_angle_deg;
  } else if (min_scale_points < 2) {
    m << "min_scale_points must be at least 2, got " << min_scale_points;
  } else if (!(min_ray_angle_deg > 0 && min_ray_angle_deg < 90)) {
    m << "min_ray_angle_deg must be in (0, 90), got " << min_ray_angle_deg;
  } else if (!(max_ray_disagreement_deg > 0 && max_ray_disagreement_deg < 90)) {
    m << "max_ray_disagreement_deg must be in (0, 90), got " << max_ray_disagreement_deg;
  } else if (!(min_median_parallax_deg >= 0 && min_median_parallax_deg < 90)) {
    m << "min_median_parallax_deg must be in [0, 90), got " << min_median_parallax_deg;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::optional<PairPose> EstimateRelativePose(const std::vector<Eigen::Vector2d>& registered,
                                             const std::vector<Eigen::Vector2d>& fresh,
                                             double focal_px,
                                             const RelativeRegistrationOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK_EQ(registered.size(), fresh.size());
  THROW_CHECK(focal_px > 0) << "focal_px must be positive";
  if (static_cast<int>(registered.size()) < options.min_pair_inliers) return std::nullopt;
  std::vector<cv::Point2d> p1, p2;
  for (std::size_t i = 0; i < registered.size(); ++i) {
    p1.emplace_back(registered[i].x(), registered[i].y());
    p2.emplace_back(fresh[i].x(), fresh[i].y());
  }
  cv::theRNG().state = kSeed;
  cv::Mat mask;
  const cv::Mat e = cv::findEssentialMat(p1, p2, 1.0, cv::Point2d(0, 0), cv::RANSAC, 0.9999,
                                         options.max_epipolar_error_px / focal_px, mask);
  if (e.rows != 3 || e.cols != 3) return std::nullopt;
  cv::Mat r_cv, t_cv;
  const int in_front = cv::recoverPose(e, p1, p2, r_cv, t_cv, 1.0, cv::Point2d(0, 0), mask);
  if (in_front < options.min_pair_inliers) return std::nullopt;
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(r_cv, r);
  cv::cv2eigen(t_cv, t);
  std::vector<Eigen::Vector3d> x1, x2;
  for (std::size_t i = 0; i < registered.size(); ++i) {
    x1.push_back(registered[i].homogeneous());
    x2.push_back(fresh[i].homogeneous());
  }
  // Every correspondence, not only RANSAC's inliers (see RefineRelativePose), then least
  // squares over the inliers of that pose: the Cauchy loss at the threshold also discounts
  // inliers a pixel off, which costs some precision at the optimum.
  const double threshold = options.max_epipolar_error_px / focal_px;
  RefineRelativePose(x1, x2, threshold, &r, &t);
  PairPose pose;
  const auto classify = [&] {
    const Eigen::VectorXd residuals = SampsonResiduals(r, t, x1, x2);
    pose.inliers.assign(x1.size(), false);
    pose.num_inliers = 0;
    for (std::size_t i = 0; i < x1.size(); ++i) {
      pose.inliers[i] =
          std::abs(residuals[i]) < threshold && Depths(r, t, x1[i], x2[i]).minCoeff() > 0;
      pose.num_inliers += pose.inliers[i];
    }
  };
  classify();
  std::vector<Eigen::Vector3d> y1, y2;
  for (std::size_t i = 0; i < x1.size(); ++i) {
    if (!pose.inliers[i]) continue;
    y1.push_back(x1[i]);
    y2.push_back(x2[i]);
  }
  RefineRelativePose(y1, y2, std::numeric_limits<double>::infinity(), &r, &t);
  classify();
  pose.new_from_registered = Rigid3d(r, t);
  if (pose.num_inliers < options.min_pair_inliers) return std::nullopt;
  std::vector<double> parallax;
  for (std::size_t i = 0; i < x1.size(); ++i) {
    if (!pose.inliers[i]) continue;
    const Eigen::Vector3d ray2 = r.transpose() * x2[i];  // In the registered photo's frame.
    parallax.push_back(Degrees(std::atan2(x1[i].cross(ray2).norm(), x1[i].dot(ray2))));
  }
  std::nth_element(parallax.begin(), parallax.begin() + parallax.size() / 2, parallax.end());
  pose.median_parallax_deg = parallax[parallax.size() / 2];
  return pose;
}

std::optional<RelativeRegistration> RegisterFromPoints(
    const NeighbourPose& neighbour,
    const std::vector<Eigen::Vector3d>& points,
    const std::vector<Eigen::Vector2d>& observations,
    const RelativeRegistrationOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK_EQ(points.size(), observations.size());
  const Eigen::Matrix3d r_rel = neighbour.relative.new_from_registered.rotation.toRotationMatrix();
  const Eigen::Vector3d w = neighbour.relative.new_from_registered.translation;
  const Eigen::Matrix3d r_new =
      r_rel * neighbour.registered_cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d t0 = r_rel * neighbour.registered_cam_from_world.translation;
  // In the new camera, point k is at v_k + s w; its ray x̃_k is parallel when
  // x̃_k × v_k + s x̃_k × w = 0.
  const std::size_t n = points.size();
  std::vector<Eigen::Vector3d> a(n), b(n), v(n);
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d x = observations[k].homogeneous();
    v[k] = r_new * points[k] + t0;
    a[k] = x.cross(v[k]);
    b[k] = x.cross(w);
  }
  auto agreeing = [&](double s, std::vector<std::size_t>* which) {
    which->clear();
    if (!(s > 0)) return;
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector3d y = v[k] + s * w;
      if (y.z() <= 0) continue;
      const Eigen::Vector3d x = observations[k].homogeneous();
      const double angle = std::atan2(x.cross(y).norm(), x.dot(y));
      if (Degrees(angle) <= options.max_scale_angle_deg) which->push_back(k);
    }
  };
  double best_scale = 0.0;
  std::vector<std::size_t> best, inliers;
  for (std::size_t k = 0; k < n; ++k) {
    const double bb = b[k].squaredNorm();
    if (bb <= 0) continue;
    agreeing(-a[k].dot(b[k]) / bb, &inliers);
    if (inliers.size() > best.size()) {
      best = inliers;
      best_scale = -a[k].dot(b[k]) / bb;
    }
  }
  // Least squares over the agreeing points, twice (the set may change once).
  for (int round = 0; round < 2 && !best.empty(); ++round) {
    double ab = 0.0, bb = 0.0;
    for (std::size_t k : best) {
      ab += a[k].dot(b[k]);
      bb += b[k].squaredNorm();
    }
    agreeing(-ab / bb, &inliers);
    if (inliers.size() < best.size()) break;
    best = inliers;
    best_scale = -ab / bb;
  }
  if (static_cast<int>(best.size()) < options.min_scale_points) return std::nullopt;
  RelativeRegistration out;
  out.cam_from_world = Rigid3d(r_new, t0 + best_scale * w);
  out.method = RelativeRegistration::Method::kPoints;
  out.num_points = static_cast<int>(best.size());
  return out;
}

std::optional<RelativeRegistration> RegisterFromRays(const std::vector<NeighbourPose>& neighbours,
                                                     const RelativeRegistrationOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  if (neighbours.size() < 2) return std::nullopt;
  std::vector<Ray> rays;
  std::vector<Eigen::Matrix3d> rotations;
  for (const NeighbourPose& n : neighbours) {
    rays.push_back(RayOf(n));
    rotations.push_back(rays.back().rotation);
  }
  double widest = 0.0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) {
      const double c = std::abs(rays[i].direction.dot(rays[j].direction));
      widest = std::max(widest, Degrees(std::acos(std::min(1.0, c))));
    }
  }
  if (widest < options.min_ray_angle_deg) return std::nullopt;
  const Eigen::Matrix3d rotation = ChordalMean(rotations);
  for (const Eigen::Matrix3d& r : rotations) {
    if (Degrees(Eigen::AngleAxisd(r * rotation.transpose()).angle()) >
        options.max_ray_disagreement_deg) {
      return std::nullopt;
    }
  }
  // The point nearest to all lines: Σ (I - d dᵀ) (C - o) = 0.
  Eigen::Matrix3d lhs = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (const Ray& ray : rays) {
    const Eigen::Matrix3d p =
        Eigen::Matrix3d::Identity() - ray.direction * ray.direction.transpose();
    lhs += p;
    rhs += p * ray.origin;
  }
  const Eigen::Vector3d centre = lhs.ldlt().solve(rhs);
  if (!centre.allFinite()) return std::nullopt;
  for (const Ray& ray : rays) {
    const Eigen::Vector3d to = centre - ray.origin;
    const double along = to.dot(ray.direction);
    if (along <= 0) return std::nullopt;  // Behind the ray's origin.
    if (Degrees(std::atan2(to.cross(ray.direction).norm(), along)) >
        options.max_ray_disagreement_deg) {
      return std::nullopt;
    }
  }
  RelativeRegistration out;
  out.cam_from_world = Rigid3d(rotation, -(rotation * centre));
  out.method = RelativeRegistration::Method::kRays;
  out.num_rays = static_cast<int>(rays.size());
  return out;
}

}  // namespace reconduit
