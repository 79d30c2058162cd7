// Internal to core/texture: a minimal triangle rasterizer shared by the visibility z-buffer and
// RenderTexturedMesh.
//
// Pixel centres sit at integer coordinates (core/geometry/camera.h); a pixel belongs to a
// triangle when its centre lies inside or on an edge (pixels on an edge shared by two triangles
// are visited for both, which a depth test resolves). Barycentric coordinates are those of the
// projected (screen-space) triangle; callers that interpolate attributes perspective-correctly
// weight them by 1 / z.
#ifndef RECONDUIT_CORE_TEXTURE_RASTERIZE_H_
#define RECONDUIT_CORE_TEXTURE_RASTERIZE_H_

#include "core/geometry/camera.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <optional>

namespace reconduit::texture_internal {

// Calls fn(x, y, b0, b1, b2) for every pixel (x, y) of the width x height image whose centre is
// inside the triangle p0 p1 p2, with its barycentric coordinates (b0 + b1 + b2 = 1). Degenerate
// triangles (area below 1e-12 px²) visit nothing.
template <typename Fn>
void RasterizeTriangle(const Eigen::Vector2d& p0,
                       const Eigen::Vector2d& p1,
                       const Eigen::Vector2d& p2,
                       int width,
                       int height,
                       Fn&& fn) {
  const double area = (p1 - p0).x() * (p2 - p0).y() - (p1 - p0).y() * (p2 - p0).x();
  if (!(std::abs(area) > 1e-12)) return;
  const int x_begin = std::max(0, static_cast<int>(std::ceil(std::min({p0.x(), p1.x(), p2.x()}))));
  const int x_end =
      std::min(width - 1, static_cast<int>(std::floor(std::max({p0.x(), p1.x(), p2.x()}))));
  const int y_begin = std::max(0, static_cast<int>(std::ceil(std::min({p0.y(), p1.y(), p2.y()}))));
  const int y_end =
      std::min(height - 1, static_cast<int>(std::floor(std::max({p0.y(), p1.y(), p2.y()}))));
  const double inv_area = 1.0 / area;
  constexpr double kEps = -1e-9;
  for (int y = y_begin; y <= y_end; ++y) {
    for (int x = x_begin; x <= x_end; ++x) {
      const double qx = x, qy = y;
      const double b0 = ((p1.x() - qx) * (p2.y() - qy) - (p1.y() - qy) * (p2.x() - qx)) * inv_area;
      const double b1 = ((p2.x() - qx) * (p0.y() - qy) - (p2.y() - qy) * (p0.x() - qx)) * inv_area;
      const double b2 = 1.0 - b0 - b1;
      if (b0 >= kEps && b1 >= kEps && b2 >= kEps) fn(x, y, b0, b1, b2);
    }
  }
}

// The pixel of a camera-frame point, through the camera's distortion; nullopt behind the camera
// or beyond the radius where the distortion folds back (there Distort is not invertible and a
// point far outside the field of view could land inside the image).
inline std::optional<Eigen::Vector2d> ProjectChecked(const Camera& camera,
                                                     const Eigen::Vector3d& point_in_cam) {
  if (!(point_in_cam.z() > 0.0)) return std::nullopt;
  const Eigen::Vector2d normalized = point_in_cam.head<2>() / point_in_cam.z();
  if (camera.k1 != 0.0 || camera.k2 != 0.0) {
    // r_d(r) = r (1 + k1 r² + k2 r⁴) must be increasing on [0, r]: r_d' = 1 + 3 k1 s + 5 k2 s²
    // (s = r²) positive at s and at its minimum when that lies in [0, s].
    const double s = normalized.squaredNorm();
    const auto derivative = [&](double t) {
      return 1.0 + 3.0 * camera.k1 * t + 5.0 * camera.k2 * t * t;
    };
    if (!(derivative(s) > 0.0)) return std::nullopt;
    if (camera.k2 > 0.0) {
      const double t_min = -3.0 * camera.k1 / (10.0 * camera.k2);
      if (t_min > 0.0 && t_min < s && !(derivative(t_min) > 0.0)) return std::nullopt;
    }
  }
  return camera.PixelFromNormalized(camera.Distort(normalized));
}

}  // namespace reconduit::texture_internal

#endif  // RECONDUIT_CORE_TEXTURE_RASTERIZE_H_
