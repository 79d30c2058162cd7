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
#include "tests/long_test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
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

// Renders the box room from cameras [first, end) of `truth` into root/images as JPEG files
// without EXIF and runs the pipeline up to sparse in root/work.
void RenderAndRunSparse(const fs::path& root,
                        const std::vector<Rigid3d>& truth,
                        std::size_t first,
                        std::size_t end,
                        Workspace* workspace) {
  fs::remove_all(root);
  fs::create_directories(root / "images");
  const TexturedScene scene = MakeBoxRoomScene(3);
  const Camera camera = Camera::FromFocal(kWidth, kHeight, kFocal);
  for (std::size_t i = first; i < end; ++i) {
    const RenderedView view = RenderScene(scene, camera, truth[i]);
    const fs::path path = root / "images" / ("view" + std::to_string(i) + ".jpg");
    ASSERT_TRUE(cv::imwrite(path.string(), view.image, {cv::IMWRITE_JPEG_QUALITY, 95}));
    workspace->images.push_back({path, path.filename().string()});
  }
  workspace->work_dir = root / "work";
  workspace->output_dir = root / "output";
  auto stages = CreatePipelineStages("sparse");
  ASSERT_TRUE(stages.ok()) << stages.status();
  const PipelineResult result = RunPipeline(*stages, *workspace, PipelineOptions(), CancelToken());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.failed_stage << ": " << result.message;
}

TEST(SparsePipeline, RecoversRenderedCamerasWithoutExif) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_sparse_pipeline_test_" + std::to_string(getpid()));
  const std::vector<Rigid3d> truth = Cameras(8);
  Workspace workspace;
  ASSERT_NO_FATAL_FAILURE(RenderAndRunSparse(root, truth, 0, truth.size(), &workspace));

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
  EXPECT_FALSE(record.contains("final_focal_warning")) << "8 photos estimate their focal";
  fs::remove_all(root);
}

// Two photos without EXIF cannot estimate their focal length: the model keeps the guess, and
// the calibration record (which the job's summary carries) says so.
TEST(SparsePipeline, TwoPhotosWithoutExifSayTheirFocalIsAGuess) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_sparse_two_photos_test_" + std::to_string(getpid()));
  const std::vector<Rigid3d> truth = Cameras(8);
  Workspace workspace;
  ASSERT_NO_FATAL_FAILURE(RenderAndRunSparse(root, truth, 3, 5, &workspace));
  std::ifstream calibration_file(workspace.StageDir("sparse") / "calibration.json");
  const nlohmann::json calibration = nlohmann::json::parse(calibration_file);
  const nlohmann::json& record = calibration.at("cameras").at(0);
  EXPECT_EQ(record.at("initial_focal_source"), "default");
  ASSERT_TRUE(record.contains("final_focal_warning"));
  const std::string warning = record.at("final_focal_warning").get<std::string>();
  std::printf("focal %.1f px (truth %.1f): %s\n", record.at("final_focal").get<double>(), kFocal,
              warning.c_str());
  EXPECT_NE(warning.find("a guess: the model has 2 photo(s)"), std::string::npos) << warning;
  fs::remove_all(root);
}

// Photos at `centres_deg` azimuths on a circle of 3 m around the room's centre, 1.5 m high
// (jittered), each looking outward at the wall behind it: a walk around a courtyard.
std::vector<Rigid3d> CourtyardWalk(const std::vector<double>& azimuths_deg) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Rigid3d> poses;
  for (const double azimuth_deg : azimuths_deg) {
    const double a = azimuth_deg * M_PI / 180.0;
    const Eigen::Vector3d out(std::cos(a), std::sin(a), 0.0);
    const Eigen::Vector3d centre = 3.0 * out + Eigen::Vector3d(0.0, 0.0, 1.5 + 0.2 * u(rng));
    const Eigen::Vector3d target = 6.0 * out + Eigen::Vector3d(0.0, 0.0, 1.2 + 0.4 * u(rng));
    poses.push_back(Rigid3d::LookAt(centre, target, Eigen::Vector3d::UnitZ()));
  }
  return poses;
}

// Renders `truth` as JPEGs without EXIF, runs the pipeline up to the sparse stage, and returns
// how many models it made, the photos of the first, and the mean error of the relative
// rotations between every two of them (degrees).
struct LoopFigures {
  int models = 0;
  std::size_t registered = 0;
  double relative_rotation_deg = 0.0;
};

LoopFigures RunSparseOnRenders(const std::vector<Rigid3d>& truth,
                               const std::string& name,
                               const Camera& camera = Camera::FromFocal(kWidth, kHeight, kFocal)) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_sparse_" + name + "_" + std::to_string(getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "images");
  const TexturedScene scene = MakeBoxRoomScene(3);
  Workspace workspace;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const RenderedView view = RenderScene(scene, camera, truth[i]);
    char file[32];
    std::snprintf(file, sizeof(file), "view%02zu.jpg", i);
    const fs::path path = root / "images" / file;
    EXPECT_TRUE(cv::imwrite(path.string(), view.image, {cv::IMWRITE_JPEG_QUALITY, 95}));
    workspace.images.push_back({path, file});
  }
  workspace.work_dir = root / "work";
  workspace.output_dir = root / "output";
  auto stages = CreatePipelineStages("sparse");
  EXPECT_TRUE(stages.ok()) << stages.status();
  LoopFigures figures;
  if (!stages.ok()) return figures;
  const PipelineResult result = RunPipeline(*stages, workspace, PipelineOptions(), CancelToken());
  EXPECT_EQ(result.status, StageStatus::kSuccess) << result.failed_stage << ": " << result.message;
  while (fs::exists(workspace.StageDir("sparse") /
                    ("model_" + std::to_string(figures.models) + ".json"))) {
    ++figures.models;
  }
  auto model = ReadReconstructionJson(workspace.StageDir("sparse") / "model_0.json");
  EXPECT_TRUE(model.ok()) << model.status();
  if (!model.ok()) return figures;
  figures.registered = model->images.size();
  double sum = 0.0;
  int pairs = 0;
  for (const auto& [i, first] : model->images) {
    for (const auto& [j, second] : model->images) {
      if (j <= i) continue;
      const Eigen::Matrix3d estimated =
          second.cam_from_world.rotation.toRotationMatrix() *
          first.cam_from_world.rotation.toRotationMatrix().transpose();
      const Eigen::Matrix3d expected =
          truth[j].rotation.toRotationMatrix() * truth[i].rotation.toRotationMatrix().transpose();
      sum += Eigen::AngleAxisd(estimated * expected.transpose()).angle() * 180.0 / M_PI;
      ++pairs;
    }
  }
  figures.relative_rotation_deg = pairs > 0 ? sum / pairs : 0.0;
  fs::remove_all(root);
  return figures;
}

// Ten photos (640 x 480, f = 600 px) on an arc of 270 deg at one height looking in at the
// boxes (a 90 deg gap). A
// common shift of cy tilts all of them together, which the structure nearly absorbs: the
// principal point's free solve put cy 15 px off the true centre (its standard deviation
// 16 px) while cx, fixed to 0.06 px, had moved 0.3 px, enough for the model selection to take
// both, and every camera tilted: relative rotations 1.44 deg, focal 0.57 % off. The decision
// now holds a coordinate known this poorly at the centre: 0.08 deg, focal 0.03 %.
TEST(SparsePipeline, RenderedInwardArcHoldsAPoorlyDeterminedPrincipalPointCoordinate) {
  const LoopFigures figures = RunSparseOnRenders(BoxRoomCameraRing(10, 270.0), "inward_arc",
                                                 Camera::FromFocal(640, 480, 600.0));
  std::printf("inward arc of 10 photos over 270 deg: %zu registered, relative rotation %.3f deg\n",
              figures.registered, figures.relative_rotation_deg);
  EXPECT_EQ(figures.registered, 10u);
  EXPECT_LT(figures.relative_rotation_deg, 0.3);
}

// Issue 13: a loop of 24 photos around a courtyard (15 deg apart, the last beside the first)
// comes out as one model with every photo, and its relative rotations are as accurate as
// those of an open walk of 24 photos (10 deg apart, 230 deg: no loop to close). Long (label
// long, tests/sparse_loop_test; about 3 minutes here).
TEST(SparsePipeline, RenderedCourtyardLoopIsOneModelAsAccurateAsAnOpenWalk) {
  if (!testing_util::LongTestsEnabled()) {
    GTEST_SKIP() << "a long test: ctest -L long -R sparse_loop (RECONDUIT_LONG_TESTS=1)";
  }
  std::vector<double> loop_deg, open_deg;
  for (int i = 0; i < 24; ++i) {
    loop_deg.push_back(15.0 * i);
    open_deg.push_back(10.0 * i);
  }
  const LoopFigures loop = RunSparseOnRenders(CourtyardWalk(loop_deg), "loop");
  const LoopFigures open = RunSparseOnRenders(CourtyardWalk(open_deg), "open");
  std::printf(
      "courtyard loop: %d model(s), %zu/24 in the first, relative rotation %.4f deg; "
      "open walk: %d model(s), %zu/24, %.4f deg\n",
      loop.models, loop.registered, loop.relative_rotation_deg, open.models, open.registered,
      open.relative_rotation_deg);
  EXPECT_EQ(loop.models, 1);
  EXPECT_EQ(loop.registered, 24u);
  EXPECT_EQ(open.registered, 24u);
  EXPECT_LT(loop.relative_rotation_deg, 0.1);
  EXPECT_LE(loop.relative_rotation_deg, 1.5 * open.relative_rotation_deg + 0.01);
}

}  // namespace
}  // namespace reconduit
