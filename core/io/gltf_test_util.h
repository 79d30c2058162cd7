// Synthetic inputs with known answers for the model.glb tests (core/io/gltf_test.cc and the
// browser test's writer, tests/gltf/write_test_glb.cc): a textured cube and cameras around it.
#ifndef RECONDUIT_CORE_IO_GLTF_TEST_UTIL_H_
#define RECONDUIT_CORE_IO_GLTF_TEST_UTIL_H_

#include "core/io/gltf.h"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace reconduit::testing_util {

// The colour (RGB) of side s of the cube: each side has its own cell of the atlas.
inline Eigen::Matrix<std::uint8_t, 3, 1> SideColor(int side) {
  static const std::array<std::array<int, 3>, 6> kColors = {{{220, 40, 40},
                                                             {40, 200, 60},
                                                             {50, 70, 230},
                                                             {230, 210, 40},
                                                             {200, 50, 210},
                                                             {40, 210, 220}}};
  const auto& c = kColors[static_cast<std::size_t>(side)];
  return {static_cast<std::uint8_t>(c[0]), static_cast<std::uint8_t>(c[1]),
          static_cast<std::uint8_t>(c[2])};
}

// An axis-aligned cube of half-size `half` around `center`, 8 vertices, 12 faces CCW from
// outside, sides in the order +x, -x, +y, -y, +z, -z (faces 2s and 2s + 1 are side s).
// With `pages` = 1 or 2 it is textured: each side fills an inset cell of a 3 x 2 grid of
// 32-px cells in a 96 x 64 page, in its SideColor; with 2 pages sides 0-2 are on page 0 and
// 3-5 on page 1 (in the cells of the same index). pages = 0: vertex colours and normals.
inline TriangleMesh MakeCube(const Eigen::Vector3f& center, float half, int pages) {
  TriangleMesh mesh;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3f corner(i >> 2 & 1, i >> 1 & 1, i & 1);
    mesh.positions.push_back(center + half * (2.0f * corner - Eigen::Vector3f::Ones()));
    mesh.normals.push_back((2.0f * corner - Eigen::Vector3f::Ones()).normalized());
    mesh.colors.push_back({static_cast<std::uint8_t>(40 + 200 * corner.x()),
                           static_cast<std::uint8_t>(40 + 200 * corner.y()),
                           static_cast<std::uint8_t>(40 + 200 * corner.z())});
  }
  auto v = [](int x, int y, int z) { return x * 4 + y * 2 + z; };
  const std::array<std::array<int, 4>, 6> quads = {
      {{v(1, 0, 0), v(1, 1, 0), v(1, 1, 1), v(1, 0, 1)},
       {v(0, 0, 0), v(0, 0, 1), v(0, 1, 1), v(0, 1, 0)},
       {v(0, 1, 0), v(0, 1, 1), v(1, 1, 1), v(1, 1, 0)},
       {v(0, 0, 0), v(1, 0, 0), v(1, 0, 1), v(0, 0, 1)},
       {v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1)},
       {v(0, 0, 0), v(0, 1, 0), v(1, 1, 0), v(1, 0, 0)}}};
  for (int s = 0; s < 6; ++s) {
    const auto& q = quads[static_cast<std::size_t>(s)];
    mesh.faces.emplace_back(q[0], q[1], q[2]);
    mesh.faces.emplace_back(q[0], q[2], q[3]);
  }
  if (pages == 0) return mesh;
  mesh.normals.clear();
  mesh.colors.clear();
  for (int p = 0; p < pages; ++p)
    mesh.texture_pages.emplace_back(64, 96, CV_8UC3, cv::Scalar(128, 128, 128));
  for (int s = 0; s < 6; ++s) {
    const int page = pages == 2 && s >= 3 ? 1 : 0;
    const int cell = pages == 2 ? s % 3 : s;
    const int cu = cell % 3, cv_row = cell / 3;
    const auto rgb = SideColor(s);
    mesh.texture_pages[static_cast<std::size_t>(page)](cv::Rect(cu * 32, cv_row * 32, 32, 32))
        .setTo(cv::Scalar(rgb[2], rgb[1], rgb[0]));
    const float u0 = (cu * 32 + 4) / 96.0f, u1 = (cu * 32 + 28) / 96.0f;
    const float v0 = (cv_row * 32 + 4) / 64.0f, v1 = (cv_row * 32 + 28) / 64.0f;
    const std::array<Eigen::Vector2f, 4> uv = {{{u0, v1}, {u1, v1}, {u1, v0}, {u0, v0}}};
    for (const std::array<int, 3>& tri :
         {std::array<int, 3>{0, 1, 2}, std::array<int, 3>{0, 2, 3}}) {
      for (int k : tri) mesh.texcoords.push_back(uv[static_cast<std::size_t>(k)]);
      mesh.face_pages.push_back(page);
    }
  }
  return mesh;
}

// `count` cameras on a circle of radius `radius` around `target`, in the plane perpendicular to
// `up`, looking at the target with image up along `up`; named 0000.jpg, 0001.jpg, ...
inline std::vector<GltfCameraView> MakeRing(const Eigen::Vector3d& target,
                                            const Eigen::Vector3d& up,
                                            double radius,
                                            int count,
                                            const Camera& camera) {
  const Eigen::Vector3d u = up.normalized();
  const Eigen::Vector3d a = u.unitOrthogonal(), b = u.cross(a);
  std::vector<GltfCameraView> views;
  for (int i = 0; i < count; ++i) {
    const double angle = 2.0 * M_PI * i / count;
    const Eigen::Vector3d center = target + radius * (std::cos(angle) * a + std::sin(angle) * b);
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.jpg", i);
    views.push_back({name, camera, Rigid3d::LookAt(center, target, u)});
  }
  return views;
}

}  // namespace reconduit::testing_util

#endif  // RECONDUIT_CORE_IO_GLTF_TEST_UTIL_H_
