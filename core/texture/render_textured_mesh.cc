#include "core/texture/render_textured_mesh.h"

#include "core/texture/rasterize.h"
#include "core/util/logging.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace reconduit {
namespace {

using texture_internal::RasterizeTriangle;

Eigen::Vector3f SampleBilinear(const cv::Mat& page, const Eigen::Vector2f& uv) {
  // glTF uv: (0, 0) is the page's top-left corner, so pixel centre i sits at (i + 0.5) / size.
  const float x = std::clamp(uv.x() * page.cols - 0.5f, 0.0f, page.cols - 1.0f);
  const float y = std::clamp(uv.y() * page.rows - 0.5f, 0.0f, page.rows - 1.0f);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, page.cols - 1), y1 = std::min(y0 + 1, page.rows - 1);
  const float fx = x - x0, fy = y - y0;
  const auto at = [&](int r, int c) {
    const cv::Vec3b& v = page.at<cv::Vec3b>(r, c);
    return Eigen::Vector3f(v[0], v[1], v[2]);
  };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x1)) +
         fy * ((1 - fx) * at(y1, x0) + fx * at(y1, x1));
}

void CheckMesh(const TriangleMesh& mesh) {
  const int num_vertices = static_cast<int>(mesh.positions.size());
  for (const Eigen::Vector3i& face : mesh.faces) {
    THROW_CHECK(face.minCoeff() >= 0 && face.maxCoeff() < num_vertices);
  }
  if (!mesh.HasTexture()) return;
  THROW_CHECK_EQ(mesh.texcoords.size(), 3 * mesh.faces.size());
  THROW_CHECK_EQ(mesh.face_pages.size(), mesh.faces.size());
  for (const int page : mesh.face_pages) {
    THROW_CHECK(page >= 0 && page < static_cast<int>(mesh.texture_pages.size()));
  }
  for (const cv::Mat& page : mesh.texture_pages) THROW_CHECK_EQ(page.type(), CV_8UC3);
}

// The colour of face f at screen barycentrics (b0, b1, b2), given 1 / z at its corners.
Eigen::Vector3f ShadePixel(
    const TriangleMesh& mesh, std::size_t f, const double w[3], double b0, double b1, double b2) {
  // Perspective-correct weights: screen barycentrics divided by depth, renormalised.
  const double p0 = b0 * w[0], p1 = b1 * w[1], p2 = b2 * w[2];
  const double sum = p0 + p1 + p2;
  const float q0 = static_cast<float>(p0 / sum), q1 = static_cast<float>(p1 / sum),
              q2 = static_cast<float>(p2 / sum);
  if (mesh.HasTexture()) {
    const Eigen::Vector2f uv = q0 * mesh.texcoords[3 * f] + q1 * mesh.texcoords[3 * f + 1] +
                               q2 * mesh.texcoords[3 * f + 2];
    return SampleBilinear(mesh.texture_pages[mesh.face_pages[f]], uv);
  }
  if (mesh.colors.size() == mesh.positions.size()) {
    const Eigen::Vector3i& face = mesh.faces[f];
    const Eigen::Vector3f rgb = q0 * mesh.colors[face[0]].cast<float>() +
                                q1 * mesh.colors[face[1]].cast<float>() +
                                q2 * mesh.colors[face[2]].cast<float>();
    return Eigen::Vector3f(rgb.z(), rgb.y(), rgb.x());  // RGB -> BGR.
  }
  return Eigen::Vector3f(128.0f, 128.0f, 128.0f);
}

MeshRender RenderPinhole(const TriangleMesh& mesh,
                         const Camera& camera,
                         const Rigid3d& cam_from_world,
                         const MeshRenderOptions& options) {
  MeshRender render;
  render.image = cv::Mat(camera.height, camera.width, CV_8UC3, options.background);
  render.coverage = cv::Mat::zeros(camera.height, camera.width, CV_8UC1);
  render.depth = cv::Mat::zeros(camera.height, camera.width, CV_32FC1);
  std::vector<Eigen::Vector3d> in_cam(mesh.positions.size());
  for (std::size_t i = 0; i < in_cam.size(); ++i) {
    in_cam[i] = cam_from_world * mesh.positions[i].cast<double>();
  }
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[f];
    const Eigen::Vector3d& a = in_cam[face[0]];
    const Eigen::Vector3d& b = in_cam[face[1]];
    const Eigen::Vector3d& c = in_cam[face[2]];
    if (!(a.z() > options.near && b.z() > options.near && c.z() > options.near)) continue;
    if (options.cull_back_faces && !((b - a).cross(c - a).dot(a) < 0.0)) continue;
    const double w[3] = {1.0 / a.z(), 1.0 / b.z(), 1.0 / c.z()};
    const auto pixel = [&](const Eigen::Vector3d& x) {
      return camera.PixelFromNormalized(x.head<2>() / x.z());
    };
    RasterizeTriangle(
        pixel(a), pixel(b), pixel(c), camera.width, camera.height,
        [&](int x, int y, double b0, double b1, double b2) {
          const float z = static_cast<float>(1.0 / (b0 * w[0] + b1 * w[1] + b2 * w[2]));
          float& depth = render.depth.at<float>(y, x);
          if (depth > 0.0f && depth <= z) return;
          depth = z;
          const Eigen::Vector3f color = ShadePixel(mesh, f, w, b0, b1, b2);
          render.image.at<cv::Vec3b>(y, x) =
              cv::Vec3b(cv::saturate_cast<uchar>(color.x()), cv::saturate_cast<uchar>(color.y()),
                        cv::saturate_cast<uchar>(color.z()));
          render.coverage.at<uchar>(y, x) = 255;
        });
  }
  return render;
}

}  // namespace

MeshRender RenderTexturedMesh(const TriangleMesh& mesh,
                              const Camera& camera,
                              const Rigid3d& cam_from_world,
                              const MeshRenderOptions& options) {
  std::string error;
  THROW_CHECK(camera.Check(&error)) << error;
  THROW_CHECK_GT(options.near, 0.0);
  CheckMesh(mesh);
  Camera pinhole = camera;
  pinhole.k1 = pinhole.k2 = 0.0;
  MeshRender render = RenderPinhole(mesh, pinhole, cam_from_world, options);
  if (camera.k1 == 0.0 && camera.k2 == 0.0) return render;

  // Distorted pixel -> its undistorted (pinhole) position, then a lookup.
  cv::Mat map_x(camera.height, camera.width, CV_32FC1),
      map_y(camera.height, camera.width, CV_32FC1);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const auto ray = camera.CamFromImg(Eigen::Vector2d(x, y));
      const Eigen::Vector2d p =
          ray ? pinhole.PixelFromNormalized(ray->head<2>()) : Eigen::Vector2d(-1e6, -1e6);
      map_x.at<float>(y, x) = static_cast<float>(p.x());
      map_y.at<float>(y, x) = static_cast<float>(p.y());
    }
  }
  MeshRender warped;
  cv::remap(render.image, warped.image, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            options.background);
  cv::remap(render.coverage, warped.coverage, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  cv::remap(render.depth, warped.depth, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  return warped;
}

}  // namespace reconduit
