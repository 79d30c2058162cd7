// A renderable synthetic scene: textured planar quads and textured height fields (terrain) in
// the world frame (metres, +z up, see camera_layouts.h), a default "room with boxes" and a
// default "terrain of hills" built from them, and the exact distance from any point to the
// scene's surfaces (the ground truth that dense reconstructions are measured against).
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

// One hill of a height field: the smooth (C2) bump height * (1 - r^2 / radius^2)^3 at
// distance r < radius from its centre, 0 beyond. Its compact support makes a hill cost nothing
// where it is absent (rendering evaluates the terrain ~10 times per ray), and its steepest
// slope, 1.717 |height| / radius, is reached at r = radius / sqrt(5).
struct Hill {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // x, y in the world frame, metres.
  double height = 1.0;                               // Metres; negative for a hollow.
  double radius = 1.0;                               // Support radius, metres, > 0.
};

// Bounds of a height field over its rectangle (TexturedHeightField::ComputeBounds).
struct HeightFieldBounds {
  double min_height = 0.0;
  double max_height = 0.0;
  double max_slope = 0.0;  // Of |gradient|.
};

// A terrain: the smooth surface z = base_z + sum of its hills over the rectangle
// [min_xy, max_xy] of (x, y), visible from both sides. Its surface coordinates are planimetric,
// (u, v) = (x, y) - min_xy in metres, so the texture is stretched by 1 / cos(slope) along the
// slope (by 15 % at 30 deg), which matching does not mind. Analytic rather than a triangle
// mesh: heights, normals and distances are exact (no facets) and it needs no acceleration
// structure.
struct TexturedHeightField {
  Eigen::Vector2d min_xy = Eigen::Vector2d(-1.0, -1.0);
  Eigen::Vector2d max_xy = Eigen::Vector2d(1.0, 1.0);
  double base_z = 0.0;
  std::vector<Hill> hills;
  ProceduralTexture texture;

  // z of the surface above (x, y) (also outside the rectangle, where the surface ends).
  double Height(double x, double y) const;
  // Height, gradient (dz/dx, dz/dy) and Hessian at (x, y); either pointer may be null.
  double Evaluate(double x,
                  double y,
                  Eigen::Vector2d* gradient,
                  Eigen::Matrix2d* hessian = nullptr) const;
  // The unit normal at (x, y), pointing up (+z).
  Eigen::Vector3d Normal(double x, double y) const;
  // Guaranteed bounds over the rectangle, tight to a few centimetres and a few hundredths of
  // slope: the extremes over a 400 x 400 grid widened by what the surface can do between grid
  // points (the sum over hills of their steepest slope, resp. of their largest curvature
  // 6 |height| / radius^2, times half a grid diagonal). ~5 ms for 12 hills: compute once per
  // batch of rays.
  HeightFieldBounds ComputeBounds() const;
  bool Contains(double x, double y) const {
    return x >= min_xy.x() && x <= max_xy.x() && y >= min_xy.y() && y <= max_xy.y();
  }
};

struct TexturedScene {
  std::vector<TexturedQuad> quads;
  std::vector<TexturedHeightField> height_fields;
  // Colour of rays that hit nothing, BGR, [0, 255] per channel.
  Eigen::Vector3d background_color = Eigen::Vector3d(0.0, 0.0, 0.0);

  // False, with a message, for degenerate quads (zero or parallel edges), height fields with an
  // empty rectangle or a hill of radius <= 0, non-finite values, invalid textures or a
  // background colour out of range.
  bool Check(std::string* error) const;
};

// The first intersection of a ray with the scene.
struct RayHit {
  int quad = -1;          // Index into TexturedScene::quads, or -1 for a height field.
  int height_field = -1;  // Index into TexturedScene::height_fields, or -1 for a quad.
  // Ray parameter: the hit is origin + distance * direction (in units of |direction|).
  double distance = 0.0;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();     // Surface coordinates on the quad, metres.
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // World frame, metres.
};

// The nearest hit with distance > 0 of the ray origin + t direction (world frame), or
// nullopt. Computes the height fields' bounds on every call: for repeated queries use a
// SceneRayCaster (or render.h, which precomputes per-quad data too).
std::optional<RayHit> IntersectRay(const TexturedScene& scene,
                                   const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction);

// IntersectRay for many rays on one scene: the height fields' bounds are computed once. Keeps a
// reference to `scene`, which must outlive it. Thread-safe (const).
class SceneRayCaster {
 public:
  explicit SceneRayCaster(const TexturedScene& scene);
  std::optional<RayHit> Intersect(const Eigen::Vector3d& origin,
                                  const Eigen::Vector3d& direction) const;

 private:
  const TexturedScene& scene_;
  std::vector<HeightFieldBounds> bounds_;
};

// The smallest t in (0, t_max) where the ray origin + t direction meets `field`, or nullopt;
// the hit's height is within 1e-9 m of the surface. `bounds` are field.ComputeBounds().
// Sphere tracing, safe with the slope bound (no step can jump over the surface), then Newton
// steps once within 1 mm. A ray starting on the surface may return t ~ 0.
std::optional<double> IntersectHeightField(const TexturedHeightField& field,
                                           const HeightFieldBounds& bounds,
                                           const Eigen::Vector3d& origin,
                                           const Eigen::Vector3d& direction,
                                           double t_max);

// Euclidean distance from `point` to the parallelogram `quad` (its interior or its edges).
double DistanceToQuad(const TexturedQuad& quad, const Eigen::Vector3d& point);

// Euclidean distance from `point` to the surface of `field`: Newton's method for the nearest
// surface point, started below (or above) `point`, restricted to the rectangle. Exact (to
// 1e-9 m) for points nearer to the surface than its radius of curvature, where the nearest point
// is unique (all that measuring a reconstruction needs); elsewhere it may find a local minimum,
// so it is always the distance to some surface point, never less than the true distance.
double DistanceToHeightField(const TexturedHeightField& field, const Eigen::Vector3d& point);

// The distance from `point` to the nearest surface of `scene` (quads and height fields);
// infinity for an empty scene.
double DistanceToScene(const TexturedScene& scene, const Eigen::Vector3d& point);

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

// A terrain of smooth hills: one height field over [-12, 12]^2 around z = 0, with 9 hills and
// 3 hollows of 0.4-1.6 m relief and 5-9 m support radius (slopes up to ~30 deg), textured with
// one procedural texture (seed derived from `seed`). Nothing else: rays that miss it see the
// background.
TexturedScene MakeTerrainScene(std::uint64_t seed = 0);

// cam_from_world poses of an aerial survey over the terrain: a `rows` x `cols` grid of
// cameras `spacing` metres apart, centred over the origin at `altitude` metres, each looking
// straight down (nadir), image "up" towards +y. Throws CheckError for rows or cols < 1.
std::vector<Rigid3d> TerrainCameraGrid(int rows, int cols, double spacing, double altitude);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_TEXTURED_SCENE_H_
