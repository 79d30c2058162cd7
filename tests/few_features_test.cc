// Issue 13, few-feature photos: a small object on a dark, plain background, photographed in
// dim light. A ring of 16 photos (640 x 480, no EXIF) around two stacked textured boxes about
// 200 px across, their contrast squeezed to a fifth (grey levels ~5-60, as an underexposed
// photo), with sensor noise and JPEG compression. At the usual SIFT contrast threshold each
// photo yields a few hundred keypoints; the features stage detects such photos again at lower
// thresholds (SiftOptions::min_features) and the ring comes out whole.
#include "core/eval/camera_evaluation.h"
#include "core/eval/ground_truth.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/scene/render.h"
#include "core/scene/textured_scene.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 640, kHeight = 480, kPhotos = 16;
constexpr double kFocal = 620.0;

// Two boxes, one on the other, with five textured faces each (no bottom), nothing else: rays
// that miss them see the dark background.
TexturedScene SmallObjectScene() {
  TexturedScene scene;
  scene.background_color = Eigen::Vector3d(12.0, 12.0, 12.0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto add_box = [&](const Eigen::Vector3d& corner, const Eigen::Vector3d& size, double yaw) {
    const Eigen::Vector3d ex = size.x() * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0.0);
    const Eigen::Vector3d ey = size.y() * Eigen::Vector3d(-std::sin(yaw), std::cos(yaw), 0.0);
    const Eigen::Vector3d ez(0.0, 0.0, size.z());
    const auto add_quad = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                              const Eigen::Vector3d& v) {
      TexturedQuad quad;
      quad.origin = origin;
      quad.edge_u = u;
      quad.edge_v = v;
      quad.texture.seed = rng();
      quad.texture.cell_size = 0.05;
      quad.texture.base_color = {80.0 + 100.0 * unit(rng), 80.0 + 100.0 * unit(rng),
                                 80.0 + 100.0 * unit(rng)};
      scene.quads.push_back(quad);
    };
    add_quad(corner, ex, ez);
    add_quad(corner + ey, ex, ez);
    add_quad(corner, ey, ez);
    add_quad(corner + ex, ey, ez);
    add_quad(corner + ez, ex, ey);
  };
  add_box({-0.12, -0.10, 0.0}, {0.24, 0.20, 0.16}, 0.0);
  add_box({-0.06, -0.07, 0.16}, {0.13, 0.12, 0.12}, 0.5);
  return scene;
}

// 16 cameras on a ring of 1.1 m around the object, 22.5 deg apart, at 0.25-0.45 m, looking
// at points near its middle.
std::vector<Rigid3d> RingCameras() {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Rigid3d> poses;
  for (int i = 0; i < kPhotos; ++i) {
    const double a = 2.0 * M_PI * i / kPhotos;
    const Eigen::Vector3d centre(1.1 * std::cos(a), 1.1 * std::sin(a), 0.35 + 0.1 * u(rng));
    const Eigen::Vector3d target(0.03 * u(rng), 0.03 * u(rng), 0.14 + 0.03 * u(rng));
    poses.push_back(Rigid3d::LookAt(centre, target, Eigen::Vector3d::UnitZ()));
  }
  return poses;
}

// An underexposed, noisy copy of a rendered photo: contrast a fifth about grey 30, Gaussian
// noise of 1 grey level.
cv::Mat Dim(const cv::Mat& image, std::uint64_t seed) {
  cv::Mat out(image.size(), image.type());
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int y = 0; y < image.rows; ++y) {
    const cv::Vec3b* in = image.ptr<cv::Vec3b>(y);
    cv::Vec3b* o = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.cols; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double v = 30.0 + 0.2 * (in[x][c] - 128.0) + noise(rng);
        o[x][c] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
    }
  }
  return out;
}

struct RingFigures {
  CameraEvaluation evaluation;
  nlohmann::json features;  // The features stage's summary.
};

// Runs the pipeline up to the sparse stage on the photos and evaluates model_0.
RingFigures RunSparse(const std::vector<InputImage>& images,
                      const std::vector<GroundTruthCamera>& truth,
                      const fs::path& root,
                      const PipelineOptions& options) {
  Workspace workspace;
  workspace.images = images;
  workspace.work_dir = root / "work";
  workspace.output_dir = root / "output";
  fs::remove_all(workspace.work_dir);
  fs::remove_all(workspace.output_dir);
  RingFigures figures;
  auto stages = CreatePipelineStages("sparse");
  EXPECT_TRUE(stages.ok()) << stages.status();
  if (!stages.ok()) return figures;
  const PipelineResult result = RunPipeline(*stages, workspace, options, CancelToken());
  EXPECT_EQ(result.status, StageStatus::kSuccess) << result.failed_stage << ": " << result.message;
  for (const StageRecord& stage : result.stages) {
    if (stage.name == "features") figures.features = stage.summary;
  }
  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  EXPECT_TRUE(model.ok()) << model.status();
  if (model.ok()) figures.evaluation = EvaluateCameras(*model, truth);
  return figures;
}

TEST(FewFeatures, DimSmallObjectRingRegistersWhole) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_few_features_test_" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "images");
  const TexturedScene scene = SmallObjectScene();
  const Camera camera = Camera::FromFocal(kWidth, kHeight, kFocal);
  const std::vector<Rigid3d> poses = RingCameras();
  std::vector<InputImage> images;
  std::vector<GroundTruthCamera> truth;
  for (int i = 0; i < kPhotos; ++i) {
    const RenderedView view = RenderScene(scene, camera, poses[i]);
    char file[32];
    std::snprintf(file, sizeof(file), "object%02d.jpg", i);
    const fs::path path = root / "images" / file;
    ASSERT_TRUE(cv::imwrite(path.string(), Dim(view.image, i), {cv::IMWRITE_JPEG_QUALITY, 90}));
    images.push_back({path, file});
    GroundTruthCamera true_camera;
    true_camera.name = file;
    true_camera.K = camera.K();
    true_camera.cam_from_world = poses[i];
    truth.push_back(true_camera);
  }
  // RECONDUIT_FEW_FEATURES_KEEP=<folder> keeps the photos and their cameras for
  // `reconduit benchmark <folder>/images --gt <folder>/cameras_par.txt`.
  if (const char* keep = std::getenv("RECONDUIT_FEW_FEATURES_KEEP")) {
    fs::create_directories(fs::path(keep) / "images");
    fs::copy(root / "images", fs::path(keep) / "images",
             fs::copy_options::overwrite_existing | fs::copy_options::recursive);
    std::ofstream(fs::path(keep) / "cameras_par.txt") << FormatMiddleburyPar(truth);
  }

  PipelineOptions once;  // Every photo detected once at the usual threshold.
  once.min_features = 0;
  const RingFigures plain = RunSparse(images, truth, root, once);
  const RingFigures adapted = RunSparse(images, truth, root, PipelineOptions());
  const auto print = [](const char* what, const RingFigures& figures) {
    std::printf(
        "dim small object, %s: %s features a photo, %d/%d registered, relative rotation %.3f "
        "deg, focal %.3f %%\n",
        what, figures.features.value("mean_per_photo", nlohmann::json()).dump().c_str(),
        figures.evaluation.num_registered, kPhotos,
        figures.evaluation.mean_relative_rotation_error_deg,
        figures.evaluation.mean_focal_error_percent);
  };
  print("detected once", plain);
  print("detected again", adapted);
  // Measured: once, 242 features a photo and 16/16 with relative rotations 0.72 deg off,
  // focal 1.9 % (43 deg, a false model, before relative registration refused pairs with too
  // little parallax: photo 5's pose from a 1 deg-parallax pair started it; 3.3 deg before the
  // principal point's poorly determined cy stayed at the centre); again (every photo at
  // contrast 0.005, then at twice its size), 2,384 features, 16/16, 0.23 deg, focal 0.72 %.
  EXPECT_LT(plain.evaluation.mean_relative_rotation_error_deg, 2.0);
  EXPECT_EQ(adapted.features.value("adapted_photos", 0), kPhotos);
  EXPECT_GT(adapted.features.value("mean_per_photo", 0.0),
            2.0 * plain.features.value("mean_per_photo", 0.0));
  EXPECT_GE(adapted.evaluation.num_registered, 15);
  EXPECT_LT(adapted.evaluation.mean_relative_rotation_error_deg, 2.0);
  EXPECT_LT(adapted.evaluation.mean_focal_error_percent, 2.0);
  fs::remove_all(root);
}

}  // namespace
}  // namespace reconduit
