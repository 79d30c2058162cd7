// Test helpers for core/texture: meshes of the synthetic scenes' quads, views with photos
// rendered from known cameras, image comparisons.
#ifndef RECONDUIT_CORE_TEXTURE_TEXTURE_TEST_UTIL_H_
#define RECONDUIT_CORE_TEXTURE_TEXTURE_TEST_UTIL_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/render.h"
#include "core/scene/textured_scene.h"
#include "core/scene/triangle_mesh.h"
#include "core/texture/texture_mesh.h"

#include <opencv2/core.hpp>

#include <cmath>
#include <memory>
#include <string>

namespace reconduit::texture_test {

// Appends `quad` to `mesh` as an n_u x n_v grid of cells, two triangles each, counter-clockwise
// around edge_u x edge_v (that side is "outside"; `flip` turns it around).
inline void AppendQuad(const TexturedQuad& quad, int n_u, int n_v, bool flip, TriangleMesh* mesh) {
  const int base = static_cast<int>(mesh->positions.size());
  for (int j = 0; j <= n_v; ++j) {
    for (int i = 0; i <= n_u; ++i) {
      const Eigen::Vector3d p =
          quad.origin + quad.edge_u * (double(i) / n_u) + quad.edge_v * (double(j) / n_v);
      mesh->positions.push_back(p.cast<float>());
    }
  }
  const auto at = [&](int i, int j) { return base + j * (n_u + 1) + i; };
  for (int j = 0; j < n_v; ++j) {
    for (int i = 0; i < n_u; ++i) {
      Eigen::Vector3i t1(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      Eigen::Vector3i t2(at(i, j), at(i + 1, j + 1), at(i, j + 1));
      if (flip) {
        std::swap(t1[1], t1[2]);
        std::swap(t2[1], t2[2]);
      }
      mesh->faces.push_back(t1);
      mesh->faces.push_back(t2);
    }
  }
}

inline TexturedQuad MakeQuad(const Eigen::Vector3d& origin,
                             const Eigen::Vector3d& edge_u,
                             const Eigen::Vector3d& edge_v,
                             std::uint64_t seed,
                             const Eigen::Vector3d& base_color) {
  TexturedQuad quad;
  quad.origin = origin;
  quad.edge_u = edge_u;
  quad.edge_v = edge_v;
  quad.texture.seed = seed;
  quad.texture.base_color = base_color;
  return quad;
}

// A wall 4 m wide and 2 m high in the plane y = 2 facing -y (towards the cameras).
inline TexturedQuad Wall() {
  return MakeQuad({-2, 2, 0}, {4, 0, 0}, {0, 0, 2}, 11, {120, 140, 160});
}
// A 1 m panel 1.5 m in front of the wall, facing the cameras too.
inline TexturedQuad Panel() {
  return MakeQuad({-0.5, 0.5, 0.5}, {1, 0, 0}, {0, 0, 1}, 12, {60, 90, 200});
}

inline Camera TestCamera() { return Camera::FromFocal(640, 480, 500.0); }

// The pose of a camera at (x, -4, 1) looking at the wall's centre, z up.
inline Rigid3d CameraAt(double x, double z = 1.0) {
  return Rigid3d::LookAt({x, -4.0, z}, {0.0, 2.0, 1.0}, Eigen::Vector3d::UnitZ());
}

// A view whose loader returns `photo` and counts its calls.
inline TextureView MakeView(const std::string& name,
                            const Camera& camera,
                            const Rigid3d& cam_from_world,
                            const cv::Mat& photo,
                            std::shared_ptr<int> loads = nullptr) {
  TextureView view;
  view.name = name;
  view.camera = camera;
  view.cam_from_world = cam_from_world;
  view.load = [photo, loads] {
    if (loads) ++*loads;
    return photo;
  };
  return view;
}

inline TextureView RenderView(const TexturedScene& scene,
                              const std::string& name,
                              const Camera& camera,
                              const Rigid3d& cam_from_world) {
  return MakeView(name, camera, cam_from_world, RenderScene(scene, camera, cam_from_world).image);
}

// Mean absolute difference over pixels and channels where mask != 0.
inline double MeanAbsDiff(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  double sum = 0.0;
  long count = 0;
  for (int y = 0; y < a.rows; ++y) {
    for (int x = 0; x < a.cols; ++x) {
      if (!mask.at<uchar>(y, x)) continue;
      const cv::Vec3b& p = a.at<cv::Vec3b>(y, x);
      const cv::Vec3b& q = b.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) sum += std::abs(int(p[c]) - int(q[c]));
      count += 3;
    }
  }
  return count > 0 ? sum / count : 0.0;
}

}  // namespace reconduit::texture_test

#endif  // RECONDUIT_CORE_TEXTURE_TEXTURE_TEST_UTIL_H_
