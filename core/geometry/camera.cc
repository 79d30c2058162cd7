#include "core/geometry/camera.h"

#include <cmath>
#include <limits>
#include <sstream>

namespace reconduit {
namespace {

// r_d(r) = r (1 + k1 r² + k2 r⁴) and its derivative.
double DistortRadius(double r, double k1, double k2) {
  const double r2 = r * r;
  return r * (1.0 + k1 * r2 + k2 * r2 * r2);
}
double DistortRadiusDerivative(double r, double k1, double k2) {
  const double r2 = r * r;
  return 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2;
}

// The smallest positive radius where r_d'(r) = 0, or infinity if r_d is increasing on
// [0, inf). r_d' is 1 + 3 k1 s + 5 k2 s² in s = r².
double MonotoneRadiusLimit(double k1, double k2) {
  double s_min = std::numeric_limits<double>::infinity();
  if (k2 == 0.0) {
    if (k1 < 0.0) s_min = -1.0 / (3.0 * k1);
  } else {
    const double disc = 9.0 * k1 * k1 - 20.0 * k2;
    if (disc >= 0.0) {
      const double sq = std::sqrt(disc);
      for (const double s : {(-3.0 * k1 - sq) / (10.0 * k2), (-3.0 * k1 + sq) / (10.0 * k2)}) {
        if (s > 0.0) s_min = std::min(s_min, s);
      }
    }
  }
  return std::sqrt(s_min);
}

}  // namespace

Camera Camera::FromFocal(int width, int height, double focal) {
  Camera camera;
  camera.width = width;
  camera.height = height;
  camera.focal = focal;
  camera.cx = (width - 1) / 2.0;
  camera.cy = (height - 1) / 2.0;
  return camera;
}

Eigen::Matrix3d Camera::K() const {
  Eigen::Matrix3d k;
  k << focal, 0, cx, 0, focal, cy, 0, 0, 1;
  return k;
}

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& normalized) const {
  const double r2 = normalized.squaredNorm();
  return normalized * (1.0 + k1 * r2 + k2 * r2 * r2);
}

std::optional<Eigen::Vector2d> Camera::Undistort(const Eigen::Vector2d& distorted) const {
  const double rd = distorted.norm();
  if (rd == 0.0 || (k1 == 0.0 && k2 == 0.0)) return distorted;
  const double r_limit = MonotoneRadiusLimit(k1, k2);
  if (std::isfinite(r_limit) && rd >= DistortRadius(r_limit, k1, k2)) return std::nullopt;

  // Newton on f(r) = r_d(r) - rd, from r = rd, kept inside [0, r_limit) where f is increasing
  // so the root is unique; bisection steps guard against overshooting. The bracket [lo, hi]
  // is closed: a converged Newton step lands on r itself, which is then one of its ends, and
  // must end the loop rather than trigger a bisection step away from the root.
  double lo = 0.0, hi = std::isfinite(r_limit) ? r_limit : std::numeric_limits<double>::max();
  double r = std::isfinite(r_limit) ? std::min(rd, 0.5 * r_limit) : rd;
  for (int iteration = 0; iteration < 100; ++iteration) {
    const double f = DistortRadius(r, k1, k2) - rd;
    if (f == 0.0) break;
    if (f > 0.0)
      hi = std::min(hi, r);
    else
      lo = std::max(lo, r);
    const double df = DistortRadiusDerivative(r, k1, k2);
    double next = r - f / df;
    if (!(next >= lo && next <= hi))
      next = std::isfinite(hi) && hi < 1e300 ? 0.5 * (lo + hi) : 2.0 * r;
    if (std::abs(next - r) <= 1e-15 * std::max(1.0, r)) {
      r = next;
      break;
    }
    r = next;
  }
  return distorted * (r / rd);
}

std::optional<Eigen::Vector2d> Camera::ImgFromCam(const Eigen::Vector3d& point_in_cam) const {
  if (!(point_in_cam.z() > 0.0)) return std::nullopt;
  const Eigen::Vector2d normalized = point_in_cam.head<2>() / point_in_cam.z();
  return PixelFromNormalized(Distort(normalized));
}

std::optional<Eigen::Vector3d> Camera::CamFromImg(const Eigen::Vector2d& pixel) const {
  const auto undistorted = Undistort(NormalizedFromPixel(pixel));
  if (!undistorted) return std::nullopt;
  return undistorted->homogeneous();
}

double Camera::FieldOfViewXDeg() const {
  return 2.0 * std::atan2(0.5 * width, focal) * 180.0 / M_PI;
}

Camera Camera::Scaled(double scale) const {
  Camera scaled = *this;
  scaled.width = static_cast<int>(std::lround(width * scale));
  scaled.height = static_cast<int>(std::lround(height * scale));
  scaled.focal = focal * scale;
  // Pixel centres at integers: the continuous coordinate of pixel centre i is i + 0.5.
  scaled.cx = (cx + 0.5) * scale - 0.5;
  scaled.cy = (cy + 0.5) * scale - 0.5;
  return scaled;
}

bool Camera::Check(std::string* error) const {
  std::ostringstream message;
  if (width <= 0 || height <= 0) {
    message << "image size must be positive, got " << width << "x" << height;
  } else if (!std::isfinite(focal) || focal <= 0.0) {
    message << "focal length must be positive and finite, got " << focal;
  } else if (!std::isfinite(cx) || !std::isfinite(cy) || !std::isfinite(k1) || !std::isfinite(k2)) {
    message << "principal point and distortion must be finite";
  } else {
    return true;
  }
  if (error != nullptr) *error = message.str();
  return false;
}

std::ostream& operator<<(std::ostream& os, const Camera& c) {
  return os << "Camera(" << c.width << "x" << c.height << ", f=" << c.focal << ", c=(" << c.cx
            << ", " << c.cy << "), k1=" << c.k1 << ", k2=" << c.k2 << ")";
}

}  // namespace reconduit
