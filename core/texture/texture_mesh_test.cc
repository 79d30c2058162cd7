#include "core/texture/texture_mesh.h"

#include "core/scene/render.h"
#include "core/texture/rasterize.h"
#include "core/texture/render_textured_mesh.h"
#include "core/texture/texture_test_util.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <memory>

namespace reconduit {
namespace {

using texture_test::AppendQuad;
using texture_test::CameraAt;
using texture_test::MeanAbsDiff;
using texture_test::Panel;
using texture_test::TestCamera;
using texture_test::Wall;

// The wall with the panel in front of it, as a scene to render and as a mesh to texture.
struct PanelScene {
  TexturedScene scene;
  TriangleMesh mesh;
  PanelScene() {
    scene.quads = {Wall(), Panel()};
    AppendQuad(Wall(), 40, 20, false, &mesh);
    AppendQuad(Panel(), 10, 10, false, &mesh);
  }
};

std::vector<TextureView> RenderViews(const TexturedScene& scene,
                                     const Camera& camera,
                                     const std::vector<double>& xs) {
  std::vector<TextureView> views;
  for (const double x : xs) {
    views.push_back(texture_test::RenderView(scene, "x" + std::to_string(x), camera, CameraAt(x)));
  }
  return views;
}

// The held-out view, its mesh render, and the pixels compared: covered by the mesh, away
// (2 px) from its silhouette, where the direct render's antialiasing mixes in the background.
struct HeldOut {
  cv::Mat truth, render, mask;
  double coverage = 0.0;  // Covered fraction of the pixels the scene covers.
};

HeldOut RenderHeldOut(const TexturedScene& scene,
                      const TriangleMesh& textured,
                      const Rigid3d& pose) {
  HeldOut held_out;
  const RenderedView truth = RenderScene(scene, TestCamera(), pose);
  const MeshRender render = RenderTexturedMesh(textured, TestCamera(), pose);
  held_out.truth = truth.image;
  held_out.render = render.image;
  cv::erode(render.coverage, held_out.mask, cv::Mat(), cv::Point(-1, -1), 2);
  const cv::Mat scene_covered = truth.depth > 0.0f;
  held_out.coverage =
      cv::countNonZero(render.coverage & scene_covered) / double(cv::countNonZero(scene_covered));
  return held_out;
}

// The error bilinear resampling alone makes on this texture: the held-out view rendered with
// its principal point moved by half a pixel, against the unshifted render moved by half a pixel
// bilinearly (half a pixel is bilinear interpolation's worst case). The photos are noise-free,
// so what separates a re-render of the textured mesh from the direct render is resampling: the
// photo's pixels interpolated once, bilinearly, at offsets spread over [0, 1) px (average error
// below the half-pixel worst case), plus the photos' own footprint on the wall, which differs
// from the held-out view's by up to ~25 % here. The re-render's error must stay below this
// reference (measured: 5.6 against 8.2; photos with distortion 5.9; the same photos baked as if
// they had none: 16.4).
double ResamplingError(const TexturedScene& scene,
                       const Rigid3d& pose,
                       const cv::Mat& original,
                       const cv::Mat& mask) {
  Camera shifted = TestCamera();
  shifted.cx += 0.5;
  shifted.cy += 0.5;
  const cv::Mat moved_truth = RenderScene(scene, shifted, pose).image;
  cv::Mat moved;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 0.5, 0, 1, 0.5);
  cv::warpAffine(original, moved, shift, original.size(), cv::INTER_LINEAR);
  return MeanAbsDiff(moved_truth, moved, mask);
}

const Rigid3d kHeldOutPose = CameraAt(1.0, 1.4);

TEST(TextureMesh, HeldOutRenderMatchesTheDirectRender) {
  const PanelScene panel;
  const std::vector<TextureView> views = RenderViews(panel.scene, TestCamera(), {-2.0, 0.0, 2.0});
  const TextureResult result =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  const TextureSummary& s = result.summary;
  EXPECT_EQ(s.num_faces, static_cast<int>(panel.mesh.NumFaces()));
  EXPECT_EQ(s.num_unseen_faces, 0);
  EXPECT_EQ(s.num_textured_faces, s.num_faces);
  EXPECT_LE(s.num_charts, s.num_charts_greedy);
  ASSERT_TRUE(result.mesh.HasTexture());
  EXPECT_EQ(result.mesh.texcoords.size(), 3 * panel.mesh.NumFaces());
  EXPECT_EQ(s.num_pages, 1);

  const HeldOut held_out = RenderHeldOut(panel.scene, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference =
      ResamplingError(panel.scene, kHeldOutPose, held_out.truth, held_out.mask);
  std::printf(
      "charts %d greedy -> %d, pages %d; held-out: coverage %.4f, error %.2f, "
      "resampling reference %.2f\n",
      s.num_charts_greedy, s.num_charts, s.num_pages, held_out.coverage, error, reference);
  EXPECT_GT(held_out.coverage, 0.99);
  EXPECT_LT(error, reference);

  // In-sample: textured from one photo only and seen from its camera, the render is that
  // photo (resampled at texel centres, but for the affine-vs-projective interpolation within
  // a face: far below a pixel). Faces the photo does not see are hidden from it too.
  const TextureResult single =
      TextureMesh(panel.mesh, {views[1]}, TextureOptions(), nullptr, CancelToken());
  const HeldOut in_sample = RenderHeldOut(panel.scene, single.mesh, views[1].cam_from_world);
  const double in_sample_error = MeanAbsDiff(in_sample.truth, in_sample.render, in_sample.mask);
  std::printf("in-sample error %.2f, coverage %.4f\n", in_sample_error, in_sample.coverage);
  EXPECT_LT(in_sample_error, 1.0);
  EXPECT_GT(in_sample.coverage, 0.99);
}

TEST(TextureMesh, BakesDistortedPhotosThroughTheCameraModel) {
  const PanelScene panel;
  Camera distorted = TestCamera();
  distorted.k1 = -0.15;
  distorted.k2 = 0.02;
  std::vector<TextureView> views = RenderViews(panel.scene, distorted, {-2.0, 0.0, 2.0});
  const TextureResult result =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  const HeldOut held_out = RenderHeldOut(panel.scene, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference =
      ResamplingError(panel.scene, kHeldOutPose, held_out.truth, held_out.mask);

  // The same photos taken for distortion-free: texture lands up to ~10 px off.
  for (TextureView& view : views) view.camera.k1 = view.camera.k2 = 0.0;
  const TextureResult wrong =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  const HeldOut wrong_held_out = RenderHeldOut(panel.scene, wrong.mesh, kHeldOutPose);
  const double wrong_error =
      MeanAbsDiff(wrong_held_out.truth, wrong_held_out.render, held_out.mask & wrong_held_out.mask);
  std::printf(
      "distorted photos: held-out coverage %.4f, error %.2f (reference %.2f); "
      "ignoring the distortion: %.2f\n",
      held_out.coverage, error, reference, wrong_error);
  EXPECT_GT(held_out.coverage, 0.99);
  EXPECT_LT(error, reference);
  EXPECT_GT(wrong_error, 2.0 * error);
}

// A box (five faces, no bottom) in front of the wall, seen from the front, the sides and above:
// every face gets a view that truly sees it whole (the ray from that camera to the face's
// centroid reaches the face first), and the held-out render matches.
TEST(TextureMesh, BoxInFrontOfTheWallGetsViewsThatSeeIt) {
  TexturedScene scene;
  TriangleMesh mesh;
  scene.quads.push_back(Wall());
  AppendQuad(Wall(), 40, 20, false, &mesh);
  const Eigen::Vector3d o(-0.4, 0.4, 0.3);  // The box spans o + [0, 0.8] x [0, 0.8] x [0, 0.8].
  const double a = 0.8;
  const std::vector<std::pair<TexturedQuad, bool>> box = {
      {texture_test::MakeQuad(o, {a, 0, 0}, {0, 0, a}, 21, {40, 160, 90}), false},  // Front.
      {texture_test::MakeQuad(o + Eigen::Vector3d(0, a, 0), {a, 0, 0}, {0, 0, a}, 22,
                              {90, 40, 160}),
       true},  // Back (facing the wall).
      {texture_test::MakeQuad(o, {0, a, 0}, {0, 0, a}, 23, {160, 90, 40}), true},  // Left.
      {texture_test::MakeQuad(o + Eigen::Vector3d(a, 0, 0), {0, a, 0}, {0, 0, a}, 24,
                              {200, 200, 60}),
       false},  // Right.
      {texture_test::MakeQuad(o + Eigen::Vector3d(0, 0, a), {a, 0, 0}, {0, a, 0}, 25,
                              {60, 200, 200}),
       false},  // Top.
  };
  for (const auto& [quad, flip] : box) {
    scene.quads.push_back(quad);
    AppendQuad(quad, 8, 8, flip, &mesh);
  }
  std::vector<TextureView> views;
  for (const auto& [x, z] : {std::pair{-2.5, 1.0}, {0.0, 1.0}, {2.5, 1.0}, {0.0, 3.0}}) {
    views.push_back(texture_test::RenderView(scene, "v", TestCamera(), CameraAt(x, z)));
  }
  const TextureResult result = TextureMesh(mesh, views, TextureOptions(), nullptr, CancelToken());
  int hidden_labels = 0;
  for (std::size_t f = 0; f < mesh.NumFaces(); ++f) {
    const int v = result.face_views[f];
    if (v < 0) continue;
    const Eigen::Vector3i& face = mesh.faces[f];
    const Eigen::Vector3d centroid =
        (mesh.positions[face[0]] + mesh.positions[face[1]] + mesh.positions[face[2]])
            .cast<double>() /
        3.0;
    const Eigen::Vector3d center = views[v].cam_from_world.CenterInWorld();
    const auto hit = IntersectRay(scene, center, centroid - center);
    if (!hit || (hit->point - centroid).norm() > 1e-6) ++hidden_labels;
  }
  // Unseen faces: the back of the box (it faces the wall), and wall faces no view sees
  // whole. None of them is seen whole by a view: all three corners (pulled 1 % towards the
  // centroid) reached first by the rays from that camera.
  const int back_faces = 2 * 8 * 8;
  int unseen_wall = 0, unseen_but_visible = 0;
  for (std::size_t f = 0; f < mesh.NumFaces(); ++f) {
    if (result.face_views[f] >= 0) continue;
    if (f < 40 * 20 * 2) ++unseen_wall;
    const Eigen::Vector3i& face = mesh.faces[f];
    const Eigen::Vector3d centroid =
        (mesh.positions[face[0]] + mesh.positions[face[1]] + mesh.positions[face[2]])
            .cast<double>() /
        3.0;
    for (const TextureView& view : views) {
      const Eigen::Vector3d center = view.cam_from_world.CenterInWorld();
      bool whole = true;
      for (int k = 0; k < 3 && whole; ++k) {
        const Eigen::Vector3d corner =
            0.99 * mesh.positions[face[k]].cast<double>() + 0.01 * centroid;
        const auto hit = IntersectRay(scene, center, corner - center);
        const auto pixel = view.camera.ImgFromCam(view.cam_from_world * corner);
        whole = hit && (hit->point - corner).norm() < 1e-6 && pixel && view.camera.InImage(*pixel);
      }
      // Facing the camera (the back faces face the wall).
      const Eigen::Vector3d normal = (mesh.positions[face[1]] - mesh.positions[face[0]])
                                         .cross(mesh.positions[face[2]] - mesh.positions[face[0]])
                                         .cast<double>();
      if (whole && normal.dot(center - centroid) > 0.0) ++unseen_but_visible;
    }
  }
  std::printf("unseen: %d wall faces, %d box faces; seen whole by some view: %d\n", unseen_wall,
              result.summary.num_unseen_faces - unseen_wall, unseen_but_visible);
  EXPECT_EQ(unseen_but_visible, 0);
  EXPECT_EQ(result.summary.num_unseen_faces - unseen_wall, back_faces);
  std::printf("box: %d faces, %d unseen, charts %d greedy -> %d\n", result.summary.num_faces,
              result.summary.num_unseen_faces, result.summary.num_charts_greedy,
              result.summary.num_charts);
  EXPECT_EQ(hidden_labels, 0);
  for (int f = 40 * 20 * 2 + back_faces; f < 40 * 20 * 2 + 2 * back_faces; ++f) {
    EXPECT_EQ(result.face_views[f], -1);
  }

  const HeldOut held_out = RenderHeldOut(scene, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference = ResamplingError(scene, kHeldOutPose, held_out.truth, held_out.mask);
  std::printf("box held-out: coverage %.4f, error %.2f, reference %.2f\n", held_out.coverage, error,
              reference);
  EXPECT_GT(held_out.coverage, 0.99);
  EXPECT_LT(error, reference);
}

// The room with boxes of core/scene (floor, four walls, four boxes that may interpenetrate),
// seen by a ring of 8 cameras: 6 texture it, 2 are held out. Unseen faces are drawn in a colour
// the scene does not have and left out of the comparison; they are the floor beyond 80 deg from
// every view, and floor hidden behind the boxes from all six. Measured: errors 8.5 and 8.1
// against references 9.1 and 9.3.
TEST(TextureMesh, RoomWithBoxesMatchesHeldOutViews) {
  const TexturedScene scene = MakeBoxRoomScene(5);
  const std::vector<Rigid3d> ring = BoxRoomCameraRing(8);
  std::vector<Rigid3d> training, held_out_poses;
  for (std::size_t i = 0; i < ring.size(); ++i)
    (i % 4 == 1 ? held_out_poses : training).push_back(ring[i]);
  TriangleMesh mesh;
  // Outside: towards the room's middle for the floor and walls (the first five quads), away
  // from the box's middle for a box's faces (five per box).
  for (std::size_t q = 0; q < scene.quads.size(); ++q) {
    const auto middle = [&](std::size_t i) {
      const TexturedQuad& quad = scene.quads[i];
      return Eigen::Vector3d(quad.origin + 0.5 * (quad.edge_u + quad.edge_v));
    };
    Eigen::Vector3d inside(0.0, 0.0, 1.5);
    if (q >= 5) {
      const std::size_t first = 5 + (q - 5) / 5 * 5;
      inside = (middle(first) + middle(first + 1) + middle(first + 2) + middle(first + 3)) / 4.0;
    }
    const TexturedQuad& quad = scene.quads[q];
    const Eigen::Vector3d normal = quad.edge_u.cross(quad.edge_v);
    const bool towards_inside = normal.dot(inside - middle(q)) > 0.0;
    const int n_u = std::max(2, static_cast<int>(quad.edge_u.norm() / 0.15));
    const int n_v = std::max(2, static_cast<int>(quad.edge_v.norm() / 0.15));
    AppendQuad(quad, n_u, n_v, q < 5 ? !towards_inside : towards_inside, &mesh);
  }
  std::vector<TextureView> views;
  for (const Rigid3d& pose : training)
    views.push_back(texture_test::RenderView(scene, "v", TestCamera(), pose));
  TextureOptions options;
  options.unseen_color = Eigen::Vector3d(1, 2, 3);
  const TextureResult result = TextureMesh(mesh, views, options, nullptr, CancelToken());
  const TextureSummary& s = result.summary;
  std::printf(
      "room: %d faces, %d unseen, charts %d greedy -> %d, %d pages, seams %.2f -> %.2f, "
      "%.2f s\n",
      s.num_faces, s.num_unseen_faces, s.num_charts_greedy, s.num_charts, s.num_pages,
      s.seam_difference_before, s.seam_difference_after, s.total_seconds);
  EXPECT_LT(s.num_charts, s.num_charts_greedy);
  for (const Rigid3d& pose : held_out_poses) {
    const HeldOut held_out = RenderHeldOut(scene, result.mesh, pose);
    cv::Mat unseen;
    cv::inRange(held_out.render, cv::Scalar(1, 2, 3), cv::Scalar(1, 2, 3), unseen);
    const cv::Mat textured = held_out.mask & ~unseen;
    const double unseen_fraction = cv::countNonZero(unseen) / double(unseen.total());
    const double error = MeanAbsDiff(held_out.truth, held_out.render, textured);
    const double reference = ResamplingError(scene, pose, held_out.truth, textured);
    std::printf("room held-out: coverage %.4f (unseen faces %.4f), error %.2f, reference %.2f\n",
                held_out.coverage, unseen_fraction, error, reference);
    EXPECT_GT(held_out.coverage, 0.98);
    EXPECT_LT(unseen_fraction, 0.12);  // Measured: 5.7 % and 8.7 % of the image.
    EXPECT_LT(error, reference);
  }
}

TEST(TextureMesh, UnseenFacesAreGreyAndCounted) {
  PanelScene panel;
  const int seen_faces = static_cast<int>(panel.mesh.NumFaces());
  TexturedQuad behind = Wall();  // Behind the wall, facing away from every camera.
  behind.origin.y() = 3.0;
  AppendQuad(behind, 6, 3, true, &panel.mesh);
  const int unseen_faces = static_cast<int>(panel.mesh.NumFaces()) - seen_faces;
  TextureOptions options;
  options.unseen_color = Eigen::Vector3d(10, 200, 30);
  const TextureResult result =
      TextureMesh(panel.mesh, RenderViews(panel.scene, TestCamera(), {-2.0, 2.0}), options, nullptr,
                  CancelToken());
  EXPECT_EQ(result.summary.num_unseen_faces, unseen_faces);
  EXPECT_EQ(result.summary.num_textured_faces, seen_faces);
  for (int f = seen_faces; f < static_cast<int>(panel.mesh.NumFaces()); ++f) {
    EXPECT_EQ(result.face_views[f], -1);
    const cv::Mat& page = result.mesh.texture_pages[result.mesh.face_pages[f]];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2f uv = result.mesh.texcoords[3 * f + k];
      const cv::Vec3b texel = page.at<cv::Vec3b>(static_cast<int>(uv.y() * page.rows),
                                                 static_cast<int>(uv.x() * page.cols));
      EXPECT_EQ(texel, cv::Vec3b(10, 200, 30));
    }
  }
}

TEST(TextureMesh, LevelsABrighterPhoto) {
  const PanelScene panel;
  std::vector<TextureView> views;
  for (const double x : {-2.0, 0.0, 2.0}) {
    cv::Mat photo = RenderScene(panel.scene, TestCamera(), CameraAt(x)).image;
    if (x == 0.0) cv::add(photo, cv::Scalar(25, 20, 30), photo);  // Another exposure.
    views.push_back(texture_test::MakeView("x", TestCamera(), CameraAt(x), photo));
  }
  const TextureResult result =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  const TextureSummary& s = result.summary;
  std::printf("%d seam samples: difference %.2f -> %.2f\n", s.num_seam_samples,
              s.seam_difference_before, s.seam_difference_after);
  EXPECT_GT(s.num_seam_samples, 50);
  EXPECT_GT(s.seam_difference_before, 15.0);
  EXPECT_LT(s.seam_difference_after, 0.5 * s.seam_difference_before);

  TextureOptions off;
  off.level_seams = false;
  const TextureResult unlevelled = TextureMesh(panel.mesh, views, off, nullptr, CancelToken());
  EXPECT_EQ(unlevelled.summary.num_seam_samples, 0);

  // Levelling moves charts relative to each other, not the texture as a whole: the offsets
  // (levelled minus unlevelled texel at each face's centroid), weighted by each face's area in
  // its photo, average to zero, so the texture keeps the photos' average colour. (A zero mean
  // over charts instead let many small charts shift the big ones: fountain-P11 came out 5 grey
  // levels brighter than its photos.)
  Eigen::Vector3d weighted_offset = Eigen::Vector3d::Zero();
  double total_area = 0.0;
  for (std::size_t f = 0; f < panel.mesh.faces.size(); ++f) {
    const int view = result.face_views[f];
    ASSERT_EQ(view, unlevelled.face_views[f]);
    if (view < 0) continue;
    Eigen::Vector2d pixels[3];
    for (int k = 0; k < 3; ++k) {
      pixels[k] = *texture_internal::ProjectChecked(
          views[view].camera,
          views[view].cam_from_world * panel.mesh.positions[panel.mesh.faces[f][k]].cast<double>());
    }
    const Eigen::Vector2d e1 = pixels[1] - pixels[0], e2 = pixels[2] - pixels[0];
    const double area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    const auto texel = [f](const TriangleMesh& mesh) {
      const Eigen::Vector2f uv =
          (mesh.texcoords[3 * f] + mesh.texcoords[3 * f + 1] + mesh.texcoords[3 * f + 2]) / 3.0f;
      const cv::Mat& page = mesh.texture_pages[mesh.face_pages[f]];
      const cv::Vec3b c = page.at<cv::Vec3b>(static_cast<int>(uv.y() * page.rows),
                                             static_cast<int>(uv.x() * page.cols));
      return Eigen::Vector3d(c[0], c[1], c[2]);
    };
    weighted_offset += area * (texel(result.mesh) - texel(unlevelled.mesh));
    total_area += area;
  }
  ASSERT_GT(total_area, 0.0);
  weighted_offset /= total_area;
  std::printf("area-weighted mean offset %.2f %.2f %.2f\n", weighted_offset[0], weighted_offset[1],
              weighted_offset[2]);
  EXPECT_LT(weighted_offset.cwiseAbs().maxCoeff(), 0.5);
}

TEST(TextureMesh, SmallPagesMakeMorePagesWithinThePageSize) {
  const PanelScene panel;
  TextureOptions options;
  options.page_size = 128;
  options.smoothness_weight = 0.0;  // Greedy: many charts.
  const TextureResult result =
      TextureMesh(panel.mesh, RenderViews(panel.scene, TestCamera(), {-2.0, 0.0, 2.0}), options,
                  nullptr, CancelToken());
  EXPECT_GT(result.summary.num_pages, 1);
  for (const cv::Mat& page : result.mesh.texture_pages) {
    EXPECT_LE(page.cols, 128);
    EXPECT_LE(page.rows, 128);
  }
  for (const Eigen::Vector2f& uv : result.mesh.texcoords) {
    EXPECT_GE(uv.minCoeff(), 0.0f);
    EXPECT_LE(uv.maxCoeff(), 1.0f);
  }
  // Shrunk charts still show the right place, blurred: coverage stays full.
  const HeldOut held_out = RenderHeldOut(panel.scene, result.mesh, kHeldOutPose);
  EXPECT_GT(held_out.coverage, 0.99);
}

TEST(TextureMesh, TexelBudgetShrinksAllCharts) {
  const PanelScene panel;
  const std::vector<TextureView> views = RenderViews(panel.scene, TestCamera(), {-2.0, 0.0, 2.0});
  const auto texels = [](const TextureResult& result) {
    double sum = 0.0;
    for (const cv::Mat& page : result.mesh.texture_pages) sum += double(page.total());
    return sum;
  };
  const TextureResult full =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  TextureOptions options;
  options.max_megatexels = 0.25 * texels(full) / 1e6;
  const TextureResult quarter = TextureMesh(panel.mesh, views, options, nullptr, CancelToken());
  std::printf("texels %.0f -> %.0f\n", texels(full), texels(quarter));
  EXPECT_LT(texels(quarter), 0.3 * texels(full));
  const HeldOut held_out = RenderHeldOut(panel.scene, quarter.mesh, kHeldOutPose);
  EXPECT_GT(held_out.coverage, 0.99);
  // Half the resolution blurs the held-out render like the direct render halved and enlarged
  // again (bilinearly): that image's error, plus the full-resolution resampling error, bounds it
  // (measured: 15.6 against 16.8 + 8.2).
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  cv::Mat half, blurred;
  cv::resize(held_out.truth, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  cv::resize(half, blurred, held_out.truth.size(), 0, 0, cv::INTER_LINEAR);
  const double blur_error = MeanAbsDiff(held_out.truth, blurred, held_out.mask);
  const double reference =
      ResamplingError(panel.scene, kHeldOutPose, held_out.truth, held_out.mask);
  std::printf(
      "held-out error at a quarter of the texels: %.2f; half-resolution image %.2f, "
      "resampling %.2f\n",
      error, blur_error, reference);
  EXPECT_LT(error, blur_error + reference);
}

TEST(TextureMesh, LoadsEachPhotoOnceAndDoesNotDependOnThreads) {
  const PanelScene panel;
  std::vector<TextureView> views;
  std::vector<std::shared_ptr<int>> loads;
  for (const double x : {-2.0, 0.0, 2.0}) {
    loads.push_back(std::make_shared<int>(0));
    views.push_back(texture_test::MakeView(
        "x", TestCamera(), CameraAt(x), RenderScene(panel.scene, TestCamera(), CameraAt(x)).image,
        loads.back()));
  }
  TextureOptions one;
  one.num_threads = 1;
  const TextureResult a = TextureMesh(panel.mesh, views, one, nullptr, CancelToken());
  for (const auto& count : loads) EXPECT_LE(*count, 1);
  const TextureResult b = TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  EXPECT_EQ(a.face_views, b.face_views);
  ASSERT_EQ(a.mesh.texture_pages.size(), b.mesh.texture_pages.size());
  for (std::size_t p = 0; p < a.mesh.texture_pages.size(); ++p) {
    EXPECT_EQ(cv::norm(a.mesh.texture_pages[p], b.mesh.texture_pages[p], cv::NORM_INF), 0.0);
  }
}

TEST(TextureMesh, HonoursCancellationAndChecksInputs) {
  const PanelScene panel;
  std::vector<TextureView> views = RenderViews(panel.scene, TestCamera(), {0.0});
  CancelToken canceled;
  canceled.RequestCancel();
  EXPECT_THROW(TextureMesh(panel.mesh, views, TextureOptions(), nullptr, canceled), CanceledError);
  // Canceled while baking: the loader fires it.
  CancelToken during;
  views[0].load = [&, photo = views[0].load()] {
    during.RequestCancel();
    return photo;
  };
  EXPECT_THROW(TextureMesh(panel.mesh, views, TextureOptions(), nullptr, during), CanceledError);

  TextureOptions bad;
  bad.page_size = 10;
  EXPECT_THROW(TextureMesh(panel.mesh, views, bad, nullptr, CancelToken()), CheckError);
  views[0].load = [] { return cv::Mat(10, 10, CV_8UC3); };  // Not the camera's size.
  EXPECT_THROW(TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken()),
               CheckError);
  Progress progress;
  const TextureResult empty =
      TextureMesh(TriangleMesh(), views, TextureOptions(), &progress, CancelToken());
  EXPECT_FALSE(empty.mesh.HasTexture());
  // No views: every face is unseen, on one page holding the grey block.
  const TextureResult no_views =
      TextureMesh(panel.mesh, {}, TextureOptions(), nullptr, CancelToken());
  EXPECT_EQ(no_views.summary.num_unseen_faces, static_cast<int>(panel.mesh.NumFaces()));
  EXPECT_EQ(no_views.summary.num_pages, 1);
  EXPECT_EQ(no_views.mesh.face_pages.size(), panel.mesh.NumFaces());
}

}  // namespace
}  // namespace reconduit
