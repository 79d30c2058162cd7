#include "core/scene/textured_scene.h"

#include "core/scene/camera_layouts.h"
#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>

namespace reconduit {
namespace {

// Sphere tracing stops and Newton takes over within this height of the surface, metres.
constexpr double kNewtonHeight = 1e-3;
// A hit is within this height of the surface, metres.
constexpr double kHitHeight = 1e-9;
constexpr int kMaxTraceSteps = 100000;

void CheckHeightField(const TexturedHeightField& field, std::size_t i, std::ostream& message) {
  std::string texture_error;
  bool finite = field.min_xy.allFinite() && field.max_xy.allFinite() && std::isfinite(field.base_z);
  bool radii = true;
  for (const Hill& hill : field.hills) {
    finite = finite && hill.center.allFinite() && std::isfinite(hill.height) &&
             std::isfinite(hill.radius);
    radii = radii && hill.radius > 0.0;
  }
  if (!finite) {
    message << "height field " << i << ": non-finite geometry";
  } else if (!(field.min_xy.array() < field.max_xy.array()).all()) {
    message << "height field " << i << ": empty rectangle";
  } else if (!radii) {
    message << "height field " << i << ": hill radius <= 0";
  } else if (!field.texture.Check(&texture_error)) {
    message << "height field " << i << ": texture: " << texture_error;
  }
}

// The parameter interval [*t0, *t1] of the ray inside the box [lo, hi]; false when empty.
bool ClipToBox(const Eigen::Vector3d& origin,
               const Eigen::Vector3d& direction,
               const Eigen::Vector3d& lo,
               const Eigen::Vector3d& hi,
               double* t0,
               double* t1) {
  for (int axis = 0; axis < 3; ++axis) {
    if (direction[axis] == 0.0) {
      if (origin[axis] < lo[axis] || origin[axis] > hi[axis]) return false;
      continue;
    }
    double a = (lo[axis] - origin[axis]) / direction[axis];
    double b = (hi[axis] - origin[axis]) / direction[axis];
    if (a > b) std::swap(a, b);
    *t0 = std::max(*t0, a);
    *t1 = std::min(*t1, b);
  }
  return *t0 <= *t1;
}

double DistanceToSegment(const Eigen::Vector3d& point,
                         const Eigen::Vector3d& start,
                         const Eigen::Vector3d& edge) {
  const double s = std::clamp((point - start).dot(edge) / edge.squaredNorm(), 0.0, 1.0);
  return (start + s * edge - point).norm();
}

}  // namespace

double TexturedHeightField::Evaluate(double x,
                                     double y,
                                     Eigen::Vector2d* gradient,
                                     Eigen::Matrix2d* hessian) const {
  double z = base_z;
  if (gradient != nullptr) gradient->setZero();
  if (hessian != nullptr) hessian->setZero();
  for (const Hill& hill : hills) {
    const Eigen::Vector2d d(x - hill.center.x(), y - hill.center.y());
    const double inv_r2 = 1.0 / (hill.radius * hill.radius);
    const double w = 1.0 - d.squaredNorm() * inv_r2;  // 1 - s, s = r^2 / radius^2.
    if (w <= 0.0) continue;
    z += hill.height * w * w * w;
    // f = h w^3, grad w = -2 d / R^2: grad f = -6 h w^2 d / R^2, and
    // Hessian f = -6 h w / R^2 (w I - 4 d d^T / R^2).
    if (gradient != nullptr) *gradient -= 6.0 * hill.height * w * w * inv_r2 * d;
    if (hessian != nullptr) {
      *hessian -= 6.0 * hill.height * w * inv_r2 *
                  (w * Eigen::Matrix2d::Identity() - 4.0 * inv_r2 * d * d.transpose());
    }
  }
  return z;
}

double TexturedHeightField::Height(double x, double y) const { return Evaluate(x, y, nullptr); }

Eigen::Vector3d TexturedHeightField::Normal(double x, double y) const {
  Eigen::Vector2d g;
  Evaluate(x, y, &g);
  return Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
}

HeightFieldBounds TexturedHeightField::ComputeBounds() const {
  // Between grid points (at most half a diagonal away) the height changes by at most the
  // slope bound times that distance, and the slope by at most the curvature bound times it.
  double slope_bound = 0.0, curvature_bound = 0.0;
  for (const Hill& hill : hills) {
    slope_bound += 1.7174 * std::abs(hill.height) / hill.radius;
    curvature_bound += 6.0 * std::abs(hill.height) / (hill.radius * hill.radius);
  }
  constexpr int kGrid = 400;
  const Eigen::Vector2d step = (max_xy - min_xy) / kGrid;
  const double half_diagonal = 0.5 * step.norm();
  HeightFieldBounds bounds{std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(), 0.0};
  for (int i = 0; i <= kGrid; ++i) {
    for (int j = 0; j <= kGrid; ++j) {
      Eigen::Vector2d g;
      const double z = Evaluate(min_xy.x() + i * step.x(), min_xy.y() + j * step.y(), &g);
      bounds.min_height = std::min(bounds.min_height, z);
      bounds.max_height = std::max(bounds.max_height, z);
      bounds.max_slope = std::max(bounds.max_slope, g.norm());
    }
  }
  bounds.min_height -= slope_bound * half_diagonal;
  bounds.max_height += slope_bound * half_diagonal;
  bounds.max_slope = std::min(bounds.max_slope + curvature_bound * half_diagonal, slope_bound);
  return bounds;
}

bool TexturedScene::Check(std::string* error) const {
  std::ostringstream message;
  for (std::size_t i = 0; i < height_fields.size() && message.tellp() == 0; ++i) {
    CheckHeightField(height_fields[i], i, message);
  }
  for (std::size_t i = 0; i < quads.size() && message.tellp() == 0; ++i) {
    const TexturedQuad& quad = quads[i];
    std::string texture_error;
    if (!quad.origin.allFinite() || !quad.edge_u.allFinite() || !quad.edge_v.allFinite()) {
      message << "quad " << i << ": non-finite geometry";
    } else if (quad.edge_u.cross(quad.edge_v).norm() <=
               1e-9 * quad.edge_u.norm() * quad.edge_v.norm()) {
      message << "quad " << i << ": edges are zero or parallel";
    } else if (!quad.texture.Check(&texture_error)) {
      message << "quad " << i << ": texture: " << texture_error;
    }
  }
  if (message.tellp() == 0) {
    if ((background_color.array() >= 0.0).all() && (background_color.array() <= 255.0).all()) {
      return true;
    }
    message << "background_color channels must be in [0, 255]";
  }
  if (error != nullptr) *error = message.str();
  return false;
}

std::optional<RayHit> IntersectRay(const TexturedScene& scene,
                                   const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction) {
  return SceneRayCaster(scene).Intersect(origin, direction);
}

SceneRayCaster::SceneRayCaster(const TexturedScene& scene) : scene_(scene) {
  for (const TexturedHeightField& field : scene.height_fields) {
    bounds_.push_back(field.ComputeBounds());
  }
}

std::optional<RayHit> SceneRayCaster::Intersect(const Eigen::Vector3d& origin,
                                                const Eigen::Vector3d& direction) const {
  std::optional<RayHit> best;
  for (int q = 0; q < static_cast<int>(scene_.quads.size()); ++q) {
    const TexturedQuad& quad = scene_.quads[q];
    const Eigen::Vector3d normal = quad.edge_u.cross(quad.edge_v);
    const double denominator = normal.dot(direction);
    if (denominator == 0.0) continue;
    const double t = normal.dot(quad.origin - origin) / denominator;
    if (!(t > 0.0) || (best && t >= best->distance)) continue;
    // Coordinates (a, b) of the hit in the edge basis, from the dual basis of (edge_u, edge_v)
    // in the quad's plane.
    const Eigen::Vector3d w = origin + t * direction - quad.origin;
    const Eigen::Vector3d dual_u = quad.edge_v.cross(normal);
    const Eigen::Vector3d dual_v = normal.cross(quad.edge_u);
    const double a = w.dot(dual_u) / quad.edge_u.dot(dual_u);
    const double b = w.dot(dual_v) / quad.edge_v.dot(dual_v);
    if (a < 0.0 || a > 1.0 || b < 0.0 || b > 1.0) continue;
    best =
        RayHit{q, -1, t, {a * quad.edge_u.norm(), b * quad.edge_v.norm()}, origin + t * direction};
  }
  for (int f = 0; f < static_cast<int>(scene_.height_fields.size()); ++f) {
    const TexturedHeightField& field = scene_.height_fields[f];
    const double t_max = best ? best->distance : std::numeric_limits<double>::infinity();
    const std::optional<double> t =
        IntersectHeightField(field, bounds_[f], origin, direction, t_max);
    if (!t) continue;
    const Eigen::Vector3d point = origin + *t * direction;
    best = RayHit{-1, f, *t, point.head<2>() - field.min_xy, point};
  }
  return best;
}

std::optional<double> IntersectHeightField(const TexturedHeightField& field,
                                           const HeightFieldBounds& bounds,
                                           const Eigen::Vector3d& origin,
                                           const Eigen::Vector3d& direction,
                                           double t_max) {
  double t = 0.0, t_end = t_max;
  const Eigen::Vector3d lo(field.min_xy.x(), field.min_xy.y(), bounds.min_height);
  const Eigen::Vector3d hi(field.max_xy.x(), field.max_xy.y(), bounds.max_height);
  if (!ClipToBox(origin, direction, lo, hi, &t, &t_end)) return std::nullopt;
  // g(t) = ray height above the surface changes by at most `speed` per unit of t.
  const double speed =
      std::abs(direction.z()) + bounds.max_slope * direction.head<2>().norm() + 1e-300;
  Eigen::Vector2d gradient;
  double side = 0.0;    // The sign of g on the ray's side of the surface.
  double t_before = t;  // The last t on that side: the first root is beyond it.
  for (int step = 0; step < kMaxTraceSteps; ++step) {
    const Eigen::Vector3d p = origin + t * direction;
    const double g = p.z() - field.Evaluate(p.x(), p.y(), &gradient);
    if (std::abs(g) <= kHitHeight) return t > 0.0 ? std::optional<double>(t) : std::nullopt;
    if (side == 0.0) side = g > 0.0 ? 1.0 : -1.0;
    const double newton = -g / (direction.z() - gradient.dot(direction.head<2>()));
    double next;
    if (g * side < 0.0) {
      // Past the root (a Newton step overshot): Newton back, or bisect if it leaves the bracket.
      next = t + newton;
      if (!(next > t_before && next < t)) next = 0.5 * (t_before + t);
    } else {
      t_before = t;
      const double safe_step = std::abs(g) / speed;
      next = t + safe_step;
      // Near the surface, Newton on g(t) (its step is at least the safe one), where the ray
      // crosses the surface clearly (not grazing): it lands within ~g^2 of the root.
      if (std::abs(g) <= kNewtonHeight && newton > 0.0 && newton <= 20.0 * safe_step) {
        next = std::min(t + newton, t_end);  // Never jumps past an occluder's distance.
      }
    }
    if (next > t_end) return std::nullopt;
    t = next;
  }
  return std::nullopt;
}

double DistanceToQuad(const TexturedQuad& quad, const Eigen::Vector3d& point) {
  const Eigen::Vector3d normal = quad.edge_u.cross(quad.edge_v).normalized();
  const Eigen::Vector3d w = point - quad.origin;
  const Eigen::Vector3d in_plane = w - w.dot(normal) * normal;
  const Eigen::Vector3d dual_u = quad.edge_v.cross(normal);
  const Eigen::Vector3d dual_v = normal.cross(quad.edge_u);
  const double a = in_plane.dot(dual_u) / quad.edge_u.dot(dual_u);
  const double b = in_plane.dot(dual_v) / quad.edge_v.dot(dual_v);
  if (a >= 0.0 && a <= 1.0 && b >= 0.0 && b <= 1.0) return std::abs(w.dot(normal));
  const Eigen::Vector3d far_corner = quad.origin + quad.edge_u + quad.edge_v;
  return std::min({DistanceToSegment(point, quad.origin, quad.edge_u),
                   DistanceToSegment(point, quad.origin, quad.edge_v),
                   DistanceToSegment(point, far_corner, -quad.edge_u),
                   DistanceToSegment(point, far_corner, -quad.edge_v)});
}

double DistanceToHeightField(const TexturedHeightField& field, const Eigen::Vector3d& point) {
  // Minimise D(x, y) = |(x, y, f(x, y)) - point|^2 / 2 by Newton's method (Gauss-Newton where
  // the Hessian is not positive definite), with a backtracking line search, inside the
  // rectangle.
  const auto clamp = [&](const Eigen::Vector2d& xy) {
    return Eigen::Vector2d(xy.cwiseMax(field.min_xy).cwiseMin(field.max_xy));
  };
  const auto squared_distance = [&](const Eigen::Vector2d& xy) {
    return (Eigen::Vector3d(xy.x(), xy.y(), field.Height(xy.x(), xy.y())) - point).squaredNorm();
  };
  Eigen::Vector2d xy = clamp(point.head<2>());
  double best = squared_distance(xy);
  for (int iteration = 0; iteration < 50; ++iteration) {
    Eigen::Vector2d g;
    Eigen::Matrix2d h;
    const double residual = field.Evaluate(xy.x(), xy.y(), &g, &h) - point.z();
    const Eigen::Vector2d gradient = xy - point.head<2>() + residual * g;
    const Eigen::Matrix2d gauss_newton = Eigen::Matrix2d::Identity() + g * g.transpose();
    Eigen::Matrix2d hessian = gauss_newton + residual * h;
    if (!(hessian.determinant() > 0.0 && hessian.trace() > 0.0)) hessian = gauss_newton;
    const Eigen::Vector2d step = -hessian.inverse() * gradient;
    bool improved = false;
    for (double scale = 1.0; scale > 1e-3 && !improved; scale *= 0.5) {
      const Eigen::Vector2d candidate = clamp(xy + scale * step);
      const double d = squared_distance(candidate);
      if (d < best) {
        improved = true;
        best = d;
        xy = candidate;
      }
    }
    if (!improved || step.norm() < 1e-12) break;
  }
  return std::sqrt(best);
}

double DistanceToScene(const TexturedScene& scene, const Eigen::Vector3d& point) {
  double distance = std::numeric_limits<double>::infinity();
  for (const TexturedQuad& quad : scene.quads) {
    distance = std::min(distance, DistanceToQuad(quad, point));
  }
  for (const TexturedHeightField& field : scene.height_fields) {
    distance = std::min(distance, DistanceToHeightField(field, point));
  }
  return distance;
}

TexturedScene MakeBoxRoomScene(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  TexturedScene scene;
  scene.background_color = {40.0, 30.0, 20.0};
  const auto add_quad = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& edge_u,
                            const Eigen::Vector3d& edge_v) {
    TexturedQuad quad;
    quad.origin = origin;
    quad.edge_u = edge_u;
    quad.edge_v = edge_v;
    quad.texture.seed = rng();
    quad.texture.base_color = {60.0 + 140.0 * unit(rng), 60.0 + 140.0 * unit(rng),
                               60.0 + 140.0 * unit(rng)};
    scene.quads.push_back(quad);
  };

  // Floor and walls.
  constexpr double kHalf = 6.0, kWallHeight = 3.0;
  const Eigen::Vector3d up(0.0, 0.0, kWallHeight);
  add_quad({-kHalf, -kHalf, 0.0}, {2 * kHalf, 0.0, 0.0}, {0.0, 2 * kHalf, 0.0});
  add_quad({-kHalf, -kHalf, 0.0}, {2 * kHalf, 0.0, 0.0}, up);
  add_quad({kHalf, -kHalf, 0.0}, {0.0, 2 * kHalf, 0.0}, up);
  add_quad({kHalf, kHalf, 0.0}, {-2 * kHalf, 0.0, 0.0}, up);
  add_quad({-kHalf, kHalf, 0.0}, {0.0, -2 * kHalf, 0.0}, up);

  // Boxes: evenly spread azimuths (with jitter) so they do not pile up, random sizes and yaw.
  constexpr int kNumBoxes = 4;
  for (int i = 0; i < kNumBoxes; ++i) {
    const double azimuth = (i + 0.6 * unit(rng)) * 2.0 * M_PI / kNumBoxes;
    const double distance = 0.6 + 0.8 * unit(rng);
    const Eigen::Vector3d size(0.4 + 0.8 * unit(rng), 0.4 + 0.8 * unit(rng), 0.4 + 0.8 * unit(rng));
    const Eigen::Matrix3d yaw =
        Eigen::AngleAxisd(unit(rng) * M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d ex = yaw.col(0) * size.x(), ey = yaw.col(1) * size.y();
    const Eigen::Vector3d ez(0.0, 0.0, size.z());
    const Eigen::Vector3d corner =
        Eigen::Vector3d(distance * std::cos(azimuth), distance * std::sin(azimuth), 0.0) -
        0.5 * ex - 0.5 * ey;
    add_quad(corner, ex, ez);       // Side at y = 0 (box frame).
    add_quad(corner + ey, ex, ez);  // Side at y = 1.
    add_quad(corner, ey, ez);       // Side at x = 0.
    add_quad(corner + ex, ey, ez);  // Side at x = 1.
    add_quad(corner + ez, ex, ey);  // Top.
  }
  return scene;
}

std::vector<Rigid3d> BoxRoomCameraRing(int num_cameras, double arc_deg) {
  return CamerasOnArc(num_cameras, Eigen::Vector3d(0.0, 0.0, 0.4), 3.5, 1.2, arc_deg);
}

TexturedScene MakeTerrainScene(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  TexturedScene scene;
  scene.background_color = {40.0, 30.0, 20.0};
  TexturedHeightField field;
  field.min_xy = Eigen::Vector2d(-12.0, -12.0);
  field.max_xy = Eigen::Vector2d(12.0, 12.0);
  // Hills on a jittered 4 x 3 grid so that they spread over the whole area; every fourth one
  // is a hollow.
  for (int i = 0; i < 12; ++i) {
    Hill hill;
    hill.center = Eigen::Vector2d(-9.0 + 6.0 * (i % 4) + 3.0 * (unit(rng) - 0.5),
                                  -8.0 + 8.0 * (i / 4) + 4.0 * (unit(rng) - 0.5));
    hill.radius = 5.0 + 4.0 * unit(rng);
    hill.height = (i % 4 == 3 ? -1.0 : 1.0) * (0.4 + 1.2 * unit(rng));
    field.hills.push_back(hill);
  }
  field.texture.seed = rng();
  field.texture.base_color = {90.0 + 60.0 * unit(rng), 110.0 + 60.0 * unit(rng), 100.0};
  scene.height_fields.push_back(field);
  return scene;
}

std::vector<Rigid3d> TerrainCameraGrid(int rows, int cols, double spacing, double altitude) {
  THROW_CHECK_GE(rows, 1);
  THROW_CHECK_GE(cols, 1);
  std::vector<Rigid3d> cams_from_world;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const Eigen::Vector2d xy((c - 0.5 * (cols - 1)) * spacing, (r - 0.5 * (rows - 1)) * spacing);
      cams_from_world.push_back(Rigid3d::LookAt(Eigen::Vector3d(xy.x(), xy.y(), altitude),
                                                Eigen::Vector3d(xy.x(), xy.y(), 0.0),
                                                Eigen::Vector3d::UnitY()));
    }
  }
  return cams_from_world;
}

}  // namespace reconduit
