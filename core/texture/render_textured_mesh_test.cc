#include "core/texture/render_textured_mesh.h"

#include "core/texture/texture_test_util.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

// A 2 m square at z = 5 (camera frame = world frame), facing the camera at the origin, with a
// page whose pixel (i, j) has colour (i, j, 100): texcoords map the square onto the page.
TriangleMesh TexturedSquare() {
  TriangleMesh mesh;
  mesh.positions = {{-1, -1, 5}, {1, -1, 5}, {1, 1, 5}, {-1, 1, 5}};
  // Seen from the camera (looking down +z, y down), counter-clockwise: normal towards -z.
  mesh.faces = {{0, 2, 1}, {0, 3, 2}};
  cv::Mat page(64, 64, CV_8UC3);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) page.at<cv::Vec3b>(y, x) = cv::Vec3b(x * 4, y * 4, 100);
  }
  mesh.texture_pages = {page};
  const auto uv = [&](int v) {
    return Eigen::Vector2f((mesh.positions[v].x() + 1) / 2, (mesh.positions[v].y() + 1) / 2);
  };
  for (const Eigen::Vector3i& face : mesh.faces) {
    for (int k = 0; k < 3; ++k) mesh.texcoords.push_back(uv(face[k]));
  }
  mesh.face_pages = {0, 0};
  return mesh;
}

TEST(RenderTexturedMesh, DrawsTheTextureWhereTheSquareProjects) {
  const TriangleMesh mesh = TexturedSquare();
  // 2 m at 5 m with f = 160: 64 px across, page pixel = image pixel.
  const Camera camera = Camera::FromFocal(128, 128, 160.0);
  const MeshRender render = RenderTexturedMesh(mesh, camera, Rigid3d());
  ASSERT_EQ(render.image.type(), CV_8UC3);
  EXPECT_EQ(cv::countNonZero(render.coverage), 64 * 64);
  // The square spans pixel centres 32..95; image pixel (32 + i, 32 + j) shows page pixel (i, j).
  for (const auto& [i, j] : {std::pair{0, 0}, {10, 50}, {63, 63}, {31, 7}}) {
    const cv::Vec3b p = render.image.at<cv::Vec3b>(32 + j, 32 + i);
    EXPECT_NEAR(p[0], i * 4, 1) << i << "," << j;
    EXPECT_NEAR(p[1], j * 4, 1) << i << "," << j;
    EXPECT_EQ(p[2], 100);
    EXPECT_NEAR(render.depth.at<float>(32 + j, 32 + i), 5.0f, 1e-4f);
  }
  EXPECT_EQ(render.coverage.at<uchar>(10, 10), 0);
}

TEST(RenderTexturedMesh, CullsBackFacesAndKeepsTheNearest) {
  TriangleMesh mesh = TexturedSquare();
  const Camera camera = Camera::FromFocal(128, 128, 160.0);
  const Rigid3d behind(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                       Eigen::Vector3d(0, 0, 10));  // Looks at the square from z = 10.
  EXPECT_EQ(cv::countNonZero(RenderTexturedMesh(mesh, camera, behind).coverage), 0);
  MeshRenderOptions both;
  both.cull_back_faces = false;
  EXPECT_EQ(cv::countNonZero(RenderTexturedMesh(mesh, camera, behind, both).coverage), 64 * 64);

  // A second, nearer square with one colour hides the first.
  TriangleMesh two = mesh;
  for (int v = 0; v < 4; ++v) two.positions.push_back(mesh.positions[v] - Eigen::Vector3f(0, 0, 1));
  two.faces.push_back({4, 6, 5});
  two.faces.push_back({4, 7, 6});
  for (int k = 0; k < 6; ++k) two.texcoords.push_back({0.5f / 64, 0.5f / 64});
  two.face_pages = {0, 0, 0, 0};
  const MeshRender render = RenderTexturedMesh(two, camera, Rigid3d());
  EXPECT_EQ(render.image.at<cv::Vec3b>(64, 64), cv::Vec3b(0, 0, 100));
  EXPECT_NEAR(render.depth.at<float>(64, 64), 4.0f, 1e-4f);
}

TEST(RenderTexturedMesh, DistortionMovesPixelsLikeTheCameraModel) {
  const TriangleMesh mesh = TexturedSquare();
  Camera camera = Camera::FromFocal(128, 128, 160.0);
  camera.k1 = -0.2;
  const MeshRender render = RenderTexturedMesh(mesh, camera, Rigid3d());
  // The square's corner (1, 1, 5) projects where ImgFromCam says.
  const Eigen::Vector2d corner = *camera.ImgFromCam(Eigen::Vector3d(0.95, 0.95, 5));
  const int x = static_cast<int>(std::lround(corner.x())),
            y = static_cast<int>(std::lround(corner.y()));
  EXPECT_EQ(render.coverage.at<uchar>(y, x), 255);
  const cv::Vec3b p = render.image.at<cv::Vec3b>(y, x);
  EXPECT_NEAR(p[0], 4 * (0.975 * 32 + 31.5), 6);  // Page x of u = 0.975.
  const Eigen::Vector2d outside = *camera.ImgFromCam(Eigen::Vector3d(1.1, 1.1, 5));
  EXPECT_EQ(render.coverage.at<uchar>(static_cast<int>(std::lround(outside.y())),
                                      static_cast<int>(std::lround(outside.x()))),
            0);
}

TEST(RenderTexturedMesh, UsesVertexColoursWithoutATexture) {
  TriangleMesh mesh = TexturedSquare();
  mesh.texture_pages.clear();
  mesh.colors.assign(4, Eigen::Matrix<std::uint8_t, 3, 1>(10, 20, 30));  // RGB
  const MeshRender render = RenderTexturedMesh(mesh, Camera::FromFocal(128, 128, 160.0), Rigid3d());
  EXPECT_EQ(render.image.at<cv::Vec3b>(64, 64), cv::Vec3b(30, 20, 10));
  mesh.face_pages = {0, 5};
  mesh.texture_pages = {cv::Mat(4, 4, CV_8UC3)};
  EXPECT_THROW(RenderTexturedMesh(mesh, Camera::FromFocal(128, 128, 160.0), Rigid3d()), CheckError);
}

}  // namespace
}  // namespace reconduit
