#include "core/scene/textured_scene.h"

#include "core/scene/camera_layouts.h"

#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <sstream>

namespace reconduit {

bool TexturedScene::Check(std::string* error) const {
  std::ostringstream message;
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
  std::optional<RayHit> best;
  for (int q = 0; q < static_cast<int>(scene.quads.size()); ++q) {
    const TexturedQuad& quad = scene.quads[q];
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
    best = RayHit{q, t, {a * quad.edge_u.norm(), b * quad.edge_v.norm()}, origin + t * direction};
  }
  return best;
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

}  // namespace reconduit
