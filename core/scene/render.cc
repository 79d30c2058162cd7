#include "core/scene/render.h"

#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

namespace reconduit {
namespace {

// A quad prepared for intersecting many rays from one camera centre C: with the ray
// C + t d, the hit is at t = numerator / normal.d and has surface coordinates
// u = (C - O + t d).to_u, v = (C - O + t d).to_v in metres.
struct PreparedQuad {
  Eigen::Vector3d normal;
  double numerator;
  Eigen::Vector3d center_minus_origin;
  Eigen::Vector3d to_u;
  Eigen::Vector3d to_v;
  double length_u;
  double length_v;
  const ProceduralTexture* texture;
};

struct Hit {
  const ProceduralTexture* texture;
  double t;
  double u;
  double v;
};

std::vector<PreparedQuad> PrepareQuads(const TexturedScene& scene, const Eigen::Vector3d& center) {
  std::vector<PreparedQuad> prepared;
  prepared.reserve(scene.quads.size());
  for (const TexturedQuad& quad : scene.quads) {
    PreparedQuad p;
    p.normal = quad.edge_u.cross(quad.edge_v);
    p.numerator = p.normal.dot(quad.origin - center);
    p.center_minus_origin = center - quad.origin;
    // The dual basis of (edge_u, edge_v) in the plane, scaled to give metres.
    const Eigen::Vector3d dual_u = quad.edge_v.cross(p.normal);
    const Eigen::Vector3d dual_v = p.normal.cross(quad.edge_u);
    p.length_u = quad.edge_u.norm();
    p.length_v = quad.edge_v.norm();
    p.to_u = dual_u * (p.length_u / quad.edge_u.dot(dual_u));
    p.to_v = dual_v * (p.length_v / quad.edge_v.dot(dual_v));
    p.texture = &quad.texture;
    prepared.push_back(p);
  }
  return prepared;
}

// The nearest hit of the ray center + t direction with t > 0, quads first: their distance
// bounds the height fields' (slower) search.
std::optional<Hit> CastRay(const std::vector<PreparedQuad>& quads,
                           const std::vector<TexturedHeightField>& height_fields,
                           const std::vector<HeightFieldBounds>& bounds,
                           const Eigen::Vector3d& center,
                           const Eigen::Vector3d& direction) {
  std::optional<Hit> best;
  double best_t = std::numeric_limits<double>::infinity();
  for (int q = 0; q < static_cast<int>(quads.size()); ++q) {
    const PreparedQuad& quad = quads[q];
    const double denominator = quad.normal.dot(direction);
    if (denominator == 0.0) continue;
    const double t = quad.numerator / denominator;
    if (!(t > 0.0) || t >= best_t) continue;
    const Eigen::Vector3d w = quad.center_minus_origin + t * direction;
    const double u = w.dot(quad.to_u);
    if (u < 0.0 || u > quad.length_u) continue;
    const double v = w.dot(quad.to_v);
    if (v < 0.0 || v > quad.length_v) continue;
    best = Hit{quad.texture, t, u, v};
    best_t = t;
  }
  for (std::size_t f = 0; f < height_fields.size(); ++f) {
    const TexturedHeightField& field = height_fields[f];
    const std::optional<double> t =
        IntersectHeightField(field, bounds[f], center, direction, best_t);
    if (!t) continue;
    const Eigen::Vector3d point = center + *t * direction;
    best = Hit{&field.texture, *t, point.x() - field.min_xy.x(), point.y() - field.min_xy.y()};
    best_t = *t;
  }
  return best;
}

}  // namespace

bool RenderOptions::Check(std::string* error) const {
  if (samples_per_axis >= 1 && samples_per_axis <= 8) return true;
  if (error != nullptr) {
    std::ostringstream message;
    message << "samples_per_axis must be in [1, 8], got " << samples_per_axis;
    *error = message.str();
  }
  return false;
}

RenderedView RenderScene(const TexturedScene& scene,
                         const Camera& camera,
                         const Rigid3d& cam_from_world,
                         const RenderOptions& options) {
  std::string error;
  THROW_CHECK(camera.Check(&error)) << error;
  THROW_CHECK(scene.Check(&error)) << error;
  THROW_CHECK(options.Check(&error)) << error;

  const Eigen::Vector3d center = cam_from_world.CenterInWorld();
  const Eigen::Matrix3d world_from_cam_rotation =
      cam_from_world.rotation.toRotationMatrix().transpose();
  const std::vector<PreparedQuad> quads = PrepareQuads(scene, center);
  std::vector<HeightFieldBounds> bounds;
  for (const TexturedHeightField& field : scene.height_fields) {
    bounds.push_back(field.ComputeBounds());
  }

  // The world direction of the ray through `pixel`, scaled so that its camera z is 1 (the ray
  // parameter at a hit is then the depth), or nullopt beyond the distortion's fold.
  const auto ray_direction = [&](double x, double y) -> std::optional<Eigen::Vector3d> {
    const auto ray_in_cam = camera.CamFromImg(Eigen::Vector2d(x, y));
    if (!ray_in_cam) return std::nullopt;
    return world_from_cam_rotation * *ray_in_cam;
  };

  const int n = options.samples_per_axis;
  std::vector<double> offsets(n);
  for (int k = 0; k < n; ++k) offsets[k] = (k + 0.5) / n - 0.5;

  RenderedView view;
  view.image = cv::Mat(camera.height, camera.width, options.grayscale ? CV_8UC1 : CV_8UC3);
  view.depth = cv::Mat(camera.height, camera.width, CV_32FC1);
  ParallelFor(
      0, static_cast<std::size_t>(camera.height),
      [&](std::size_t row_index) {
        const int row = static_cast<int>(row_index);
        auto* depth_row = view.depth.ptr<float>(row);
        auto* image_row = view.image.ptr<std::uint8_t>(row);
        for (int col = 0; col < camera.width; ++col) {
          Eigen::Vector3d sum = Eigen::Vector3d::Zero();
          for (const double dy : offsets) {
            for (const double dx : offsets) {
              const auto direction = ray_direction(col + dx, row + dy);
              const auto hit = direction
                                   ? CastRay(quads, scene.height_fields, bounds, center, *direction)
                                   : std::nullopt;
              sum += hit ? EvaluateTexture(*hit->texture, hit->u, hit->v) : scene.background_color;
            }
          }
          const Eigen::Vector3d bgr = sum / (n * n);

          const auto center_direction = ray_direction(col, row);
          const auto center_hit = center_direction ? CastRay(quads, scene.height_fields, bounds,
                                                             center, *center_direction)
                                                   : std::nullopt;
          depth_row[col] = center_hit ? static_cast<float>(center_hit->t) : 0.0f;

          if (options.grayscale) {
            image_row[col] =
                cv::saturate_cast<std::uint8_t>(0.114 * bgr[0] + 0.587 * bgr[1] + 0.299 * bgr[2]);
          } else {
            for (int c = 0; c < 3; ++c) {
              image_row[3 * col + c] = cv::saturate_cast<std::uint8_t>(bgr[c]);
            }
          }
        }
      },
      options.num_threads);
  return view;
}

}  // namespace reconduit
