// A renderable synthetic scene: textured planar quads in the world frame (metres, +z up, see
// camera_layouts.h), and a default "room with boxes" built from them.
//
// The description is a plain struct so tests can build their own scenes; render.h turns it
// into images and depth maps.
#ifndef RECONDUIT_CORE_SCENE_TEXTURED_SCENE_H_
#define RECONDUIT_CORE_SCENE_TEXTURED_SCENE_H_

#include "core/geometry/rigid3.h"
#include "core/scene/procedural_texture.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace reconduit {

// The parallelogram {origin + a edge_u + b edge_v : a, b in [0, 1]}, visible from both sides.
// Its surface coordinates, in metres, are u = a |edge_u| and v = b |edge_v|; the texture is
// evaluated at (u, v), so its scale is metric whatever the quad's size. Make the edges
// orthogonal for an undistorted texture.
struct TexturedQuad {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   // A corner, world frame, metres.
  Eigen::Vector3d edge_u = Eigen::Vector3d::UnitX();  // Edge from `origin` along u, metres.
  Eigen::Vector3d edge_v = Eigen::Vector3d::UnitY();  // Edge from `origin` along v, metres.
  ProceduralTexture texture;

  // The world point at surface coordinates (u, v) in metres.
  Eigen::Vector3d PointAt(double u, double v) const {
    return origin + u / edge_u.norm() * edge_u + v / edge_v.norm() * edge_v;
  }
};

struct TexturedScene {
  std::vector<TexturedQuad> quads;
  // Colour of rays that hit nothing, BGR, [0, 255] per channel.
  Eigen::Vector3d background_color = Eigen::Vector3d(0.0, 0.0, 0.0);

  // False, with a message, for degenerate quads (zero or parallel edges), invalid textures or
  // a background colour out of range.
  bool Check(std::string* error) const;
};

// The first intersection of a ray with the scene.
struct RayHit {
  int quad = -1;  // Index into TexturedScene::quads.
  // Ray parameter: the hit is origin + distance * direction (in units of |direction|).
  double distance = 0.0;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();     // Surface coordinates on the quad, metres.
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // World frame, metres.
};

// The nearest hit with distance > 0 of the ray origin + t direction (world frame), or
// nullopt. For repeated queries use render.h, which precomputes per-quad data.
std::optional<RayHit> IntersectRay(const TexturedScene& scene,
                                   const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction);

// A room with textured floor and walls and a few textured boxes on the floor:
// - floor z = 0 over [-6, 6]², four walls 3 m high on its edges, no ceiling;
// - 4 boxes of 0.4-1.2 m sides with random yaw, centres 0.6-1.4 m from the origin (all
//   inside the 2.4 m radius circle; neighbours may interpenetrate), each with 5 faces (no
//   bottom).
// Every surface has its own texture seed (derived from `seed`) and base colour.
TexturedScene MakeBoxRoomScene(std::uint64_t seed = 0);

// cam_from_world poses of `num_cameras` cameras spread over an arc of `arc_deg` degrees on a
// circle of radius 3.5 m at eye height 1.6 m around the room's centre, looking at the boxes
// (the point (0, 0, 0.4)). Every view sees boxes, floor and walls.
std::vector<Rigid3d> BoxRoomCameraRing(int num_cameras, double arc_deg = 360.0);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_TEXTURED_SCENE_H_
