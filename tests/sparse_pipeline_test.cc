// The sparse pipeline end to end on rendered photos with exact ground truth: a textured room
// photographed from known cameras, written as JPEG files without EXIF, then ingest, features,
// pairs, matching and sparse reconstruction with self-calibration. The recovered cameras,
// aligned to the truth by a 7-DoF similarity (Umeyama) on their centres, must match the true
// rotations, centres and focal length.
#include "core/io/reconstruction_json.h"
#include "core/pipeline/default_stages.h"
#include "core/pipeline/runner.h"
#include "core/scene/render.h"
#include "core/scene/textured_scene.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 800, kHeight = 600;
constexpr double kFocal = 640.0;

// Cameras around the room's boxes, at varied heights and aimed at varied points so that
// their optical axes do not all meet (that configuration defeats focal self-calibration).
std::vector<Rigid3d> Cameras(int n) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Rigid3d> poses;
  for (int i = 0; i < n; ++i) {
    const double angle = (-60.0 + 120.0 * i / (n - 1)) * M_PI / 180.0;
    const Eigen::Vector3d centre(3.6 * std::sin(angle), -3.6 * std::cos(angle), 1.6 + 0.3 * u(rng));
    const Eigen::Vector3d target(0.6 * u(rng), 0.6 * u(rng), 0.4 + 0.3 * u(rng));
    poses.push_back(Rigid3d::LookAt(centre, target, Eigen::Vector3d::UnitZ()));
  }
  return poses;
}

TEST(SparsePipeline, RecoversRenderedCamerasWithoutExif) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_sparse_pipeline_test_" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "images");
  const TexturedScene scene = MakeBoxRoomScene(3);
  const Camera camera = Camera::FromFocal(kWidth, kHeight, kFocal);
  const std::vector<Rigid3d> truth = Cameras(8);
  Workspace workspace;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const RenderedView view = RenderScene(scene, camera, truth[i]);
    const fs::path path = root / "images" / ("view" + std::to_string(i) + ".jpg");
    ASSERT_TRUE(cv::imwrite(path.string(), view.image, {cv::IMWRITE_JPEG_QUALITY, 95}));
    workspace.images.push_back({path, path.filename().string()});
  }
  workspace.work_dir = root / "work";
  workspace.output_dir = root / "output";
  auto stages = CreatePipelineStages("sparse");
  ASSERT_TRUE(stages.ok()) << stages.status();
  const PipelineResult result = RunPipeline(*stages, workspace, PipelineOptions(), CancelToken());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.failed_stage << ": " << result.message;

  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  ASSERT_TRUE(model.ok()) << model.status();
  ASSERT_EQ(model->images.size(), truth.size()) << "every photo registered in one model";

  // Similarity from the reconstruction's frame to the truth, fitted on camera centres.
  Eigen::Matrix3Xd estimated(3, truth.size()), expected(3, truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    estimated.col(i) = model->images.at(static_cast<int>(i)).cam_from_world.CenterInWorld();
    expected.col(i) = truth[i].CenterInWorld();
  }
  const Eigen::Matrix4d sim = Eigen::umeyama(estimated, expected, true);
  const double scale = sim.topLeftCorner<3, 3>().col(0).norm();
  const Eigen::Matrix3d world_rotation = sim.topLeftCorner<3, 3>() / scale;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const Eigen::Vector3d aligned = (sim * estimated.col(i).homogeneous()).head<3>();
    EXPECT_LT((aligned - expected.col(i)).norm(), 0.01) << "camera " << i << " centre (m)";
    // cam_from_world rotation in the truth's frame: R_est * R_worldᵀ.
    const Eigen::Matrix3d r =
        model->images.at(static_cast<int>(i)).cam_from_world.rotation.toRotationMatrix() *
        world_rotation.transpose();
    const double angle =
        Eigen::AngleAxisd(r * truth[i].rotation.toRotationMatrix().transpose()).angle();
    EXPECT_LT(angle * 180.0 / M_PI, 0.1) << "camera " << i << " rotation (deg)";
  }
  ASSERT_EQ(model->cameras.size(), 1u) << "one camera: same size, no EXIF";
  const Camera& recovered = model->cameras.begin()->second;
  EXPECT_NEAR(recovered.focal, kFocal, 0.005 * kFocal);
  EXPECT_NEAR(recovered.k1, 0.0, 0.01);
  EXPECT_LT(model->MeanReprojectionError(), 0.5);

  // The calibration record carries the final focal and its precision (one sigma, pixels).
  std::ifstream calibration_file(workspace.StageDir("sparse") / "calibration.json");
  const nlohmann::json calibration = nlohmann::json::parse(calibration_file);
  const nlohmann::json& record = calibration.at("cameras").at(0);
  EXPECT_DOUBLE_EQ(record.at("final_focal").get<double>(), recovered.focal);
  const double focal_stddev = record.at("stddev").at("focal").get<double>();
  std::printf("focal %.3f +- %.3f px (truth %.1f)\n", recovered.focal, focal_stddev, kFocal);
  EXPECT_GT(focal_stddev, 0.0);
  EXPECT_LT(focal_stddev, 0.005 * kFocal);
  fs::remove_all(root);
}

}  // namespace
}  // namespace reconduit
