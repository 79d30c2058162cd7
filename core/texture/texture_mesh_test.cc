#include "core/texture/texture_mesh.h"

#include "core/scene/render.h"
#include "core/texture/render_textured_mesh.h"
#include "core/texture/texture_test_util.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>
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

HeldOut RenderHeldOut(const PanelScene& panel, const TriangleMesh& textured, const Rigid3d& pose) {
  HeldOut held_out;
  const RenderedView truth = RenderScene(panel.scene, TestCamera(), pose);
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
double ResamplingError(const PanelScene& panel, const Rigid3d& pose, const cv::Mat& mask) {
  Camera shifted = TestCamera();
  shifted.cx += 0.5;
  shifted.cy += 0.5;
  const cv::Mat moved_truth = RenderScene(panel.scene, shifted, pose).image;
  const cv::Mat original = RenderScene(panel.scene, TestCamera(), pose).image;
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

  const HeldOut held_out = RenderHeldOut(panel, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference = ResamplingError(panel, kHeldOutPose, held_out.mask);
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
  const HeldOut in_sample = RenderHeldOut(panel, single.mesh, views[1].cam_from_world);
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
  const HeldOut held_out = RenderHeldOut(panel, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference = ResamplingError(panel, kHeldOutPose, held_out.mask);

  // The same photos taken for distortion-free: texture lands up to ~10 px off.
  for (TextureView& view : views) view.camera.k1 = view.camera.k2 = 0.0;
  const TextureResult wrong =
      TextureMesh(panel.mesh, views, TextureOptions(), nullptr, CancelToken());
  const HeldOut wrong_held_out = RenderHeldOut(panel, wrong.mesh, kHeldOutPose);
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

  PanelScene reference_scene;  // ResamplingError needs a scene; this one has the same wall.
  reference_scene.scene = scene;
  reference_scene.mesh = mesh;
  const HeldOut held_out = RenderHeldOut(reference_scene, result.mesh, kHeldOutPose);
  const double error = MeanAbsDiff(held_out.truth, held_out.render, held_out.mask);
  const double reference = ResamplingError(reference_scene, kHeldOutPose, held_out.mask);
  std::printf("box held-out: coverage %.4f, error %.2f, reference %.2f\n", held_out.coverage, error,
              reference);
  EXPECT_GT(held_out.coverage, 0.99);
  EXPECT_LT(error, reference);
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
  const HeldOut held_out = RenderHeldOut(panel, result.mesh, kHeldOutPose);
  EXPECT_GT(held_out.coverage, 0.99);
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
