#include "core/pipeline/stages/export_stage.h"

#include "core/io/bundler.h"
#include "core/io/cameras_json.h"
#include "core/io/colmap_text.h"
#include "core/io/file_util.h"
#include "core/io/ply.h"
#include "core/io/reconstruction_json.h"
#include "core/pipeline/stages/ingest_stage.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// Every file under `dir`, relative path -> bytes.
std::map<std::string, std::string> FilesUnder(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    auto bytes = ReadFile(entry.path());
    EXPECT_TRUE(bytes.ok()) << entry.path();
    files[fs::relative(entry.path(), dir).generic_string()] = bytes.ok() ? *bytes : "";
  }
  return files;
}

// Three registered photos of two cameras (with distortion, poses and points whose doubles
// need every digit), one accepted photo left out of the model and one refused.
Reconstruction MakeModel() {
  Reconstruction rec;
  Camera a = Camera::FromFocal(640, 480, 700.0 / 3.0 * 4.0);
  a.k1 = -0.0123456789;
  a.k2 = 0.001 / 7.0;
  rec.cameras[0] = a;
  rec.cameras[1] = Camera::FromFocal(480, 640, 601.25);
  const char* names[] = {"a.jpg", "b.jpg", "", "d.jpg"};
  for (int id : {0, 1, 3}) {
    RegisteredImage image;
    image.image_id = id;
    image.camera_id = id == 3 ? 1 : 0;
    image.name = names[id];
    image.cam_from_world =
        Rigid3d(Eigen::AngleAxisd(0.1 * id + 1.0 / 7.0, Eigen::Vector3d(1, 2, 3).normalized())
                    .toRotationMatrix(),
                Eigen::Vector3d(0.3 * id, -1.0 / 3.0, 5.0 + id / 11.0));
    for (int k = 0; k < 6; ++k) image.keypoints.emplace_back(10.5 + 37.1 * k + id, 20.25 + 13 * k);
    image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
    rec.images[id] = image;
  }
  for (int k = 0; k < 5; ++k) {
    const int id = rec.AddPoint(Eigen::Vector3d(k / 3.0, -k / 7.0, 4.0 + k / 9.0),
                                {{0, k}, {1, k + 1}, {3, 5 - k}});
    rec.points[id].rgb = {static_cast<std::uint8_t>(40 * k), 200, static_cast<std::uint8_t>(k)};
    rec.points[id].error = 0.1 + k / 13.0;
  }
  return rec;
}

class ExportStageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("reconduit_export_stage_test_" + std::to_string(getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    for (const char* name : {"a.jpg", "b.jpg", "c.jpg", "d.jpg", "e.txt"})
      workspace_.images.push_back({root_ / name, name});
    workspace_.work_dir = root_ / "work";
    workspace_.output_dir = root_ / "output";
    fs::create_directories(workspace_.StageDir("ingest"));
    fs::create_directories(workspace_.StageDir("sparse"));
    fs::create_directories(workspace_.StageDir("export"));
    nlohmann::json images = nlohmann::json::array();
    for (int i = 0; i < 5; ++i) {
      IngestedImage image;
      image.index = i;
      image.name = workspace_.images[i].name;
      image.path = workspace_.images[i].path;
      image.photo.accepted = i < 4;
      if (!image.photo.accepted) image.photo.reason = "not a photo";
      image.photo.width = i == 3 ? 480 : 640;
      image.photo.height = i == 3 ? 640 : 480;
      images.push_back(image.ToJson());
      // Real photos for the thumbnails: a gradient, d.jpg upright (portrait).
      cv::Mat pixels(image.photo.height, image.photo.width, CV_8UC3);
      for (int y = 0; y < pixels.rows; ++y) pixels.row(y).setTo(cv::Scalar(y % 256, 40 * i, 128));
      if (image.photo.accepted) {
        ASSERT_TRUE(cv::imwrite(image.path.string(), pixels));
      }
    }
    ASSERT_TRUE(WriteFileAtomically(workspace_.StageDir("ingest") / "images.json",
                                    nlohmann::json{{"images", images}}.dump())
                    .ok());
  }
  void TearDown() override { fs::remove_all(root_); }

  StageResult RunExport(const std::vector<StageRecord>& previous) {
    Progress progress;
    const CancelToken cancel;
    const PipelineOptions options;
    StageContext context{workspace_, options,  progress,
                         cancel,     previous, workspace_.StageDir("export")};
    return ExportStage().Run(context);
  }

  static std::vector<StageRecord> SparseSucceeded() {
    StageRecord ingest, sparse;
    ingest.name = "ingest";
    ingest.status = StageStatus::kSuccess;
    sparse.name = "sparse";
    sparse.status = StageStatus::kSuccess;
    return {ingest, sparse};
  }

  fs::path root_;
  Workspace workspace_;
};

TEST_F(ExportStageTest, WritesTheSparseDeliverablesAsTheModelInMemoryWouldGive) {
  const Reconstruction model = MakeModel();
  ASSERT_TRUE(WriteReconstructionJson(workspace_.StageDir("sparse") / "model_0.json", model).ok());
  const StageResult result = RunExport(SparseSucceeded());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  EXPECT_EQ(result.summary["exported"], "ingest, sparse");
  EXPECT_EQ(result.summary["deliverables"], 7 + 4) << "and a thumbnail per accepted photo";

  // The same bytes as the writers give from the model in memory, the photo accepted but not
  // registered (c.jpg) listed as such.
  const fs::path expected = root_ / "expected";
  fs::create_directories(expected / "sparse");
  fs::create_directories(expected / "bundle");
  ASSERT_TRUE(WriteCamerasJson(expected / "cameras.json", model, {"c.jpg"}).ok());
  ASSERT_TRUE(WriteColmapText(expected / "sparse", model).ok());
  ASSERT_TRUE(WriteBundler(expected / "bundle", model).ok());
  ASSERT_TRUE(
      WritePointCloudPly(expected / "sparse.ply", PointCloudFromReconstruction(model)).ok());
  const auto want = FilesUnder(expected);
  auto got = FilesUnder(workspace_.output_dir);
  std::erase_if(got, [](const auto& file) { return file.first.starts_with("report/photos/"); });
  ASSERT_EQ(want.size(), 7u);
  EXPECT_EQ(got, want);
  EXPECT_NE(got.at("cameras.json").find("c.jpg"), std::string::npos);
}

TEST_F(ExportStageTest, ExportsNothingForStagesThatDidNotRun) {
  // A run stopped before sparse (--until matching): a stale model in work/ is not exported.
  ASSERT_TRUE(
      WriteReconstructionJson(workspace_.StageDir("sparse") / "model_0.json", MakeModel()).ok());
  StageRecord ingest;
  ingest.name = "ingest";
  ingest.status = StageStatus::kSuccess;
  const StageResult result = RunExport({ingest});
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  EXPECT_EQ(result.summary["exported"], "ingest");
  EXPECT_EQ(result.summary["deliverables"], 4) << "the thumbnails only";
  EXPECT_FALSE(fs::exists(workspace_.output_dir / "cameras.json"));
  EXPECT_FALSE(fs::exists(workspace_.output_dir / "sparse.ply"));
}

TEST_F(ExportStageTest, AMissingModelFailsTheStage) {
  const StageResult result = RunExport(SparseSucceeded());
  EXPECT_EQ(result.status, StageStatus::kFailed);
  EXPECT_NE(result.message.find("sparse: "), std::string::npos) << result.message;
  EXPECT_NE(result.message.find("model_0.json"), std::string::npos) << result.message;
}

// report.html's thumbnails: every accepted photo at most 256 px, upright, named by the dense
// stage's rule; a photo that cannot be read any more gets none and the export goes on.
TEST_F(ExportStageTest, WritesAThumbnailPerAcceptedPhoto) {
  fs::remove(root_ / "b.jpg");
  StageRecord ingest;
  ingest.name = "ingest";
  ingest.status = StageStatus::kSuccess;
  const StageResult result = RunExport({ingest});
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  EXPECT_EQ(result.summary["deliverables"], 3);
  const fs::path photos = workspace_.output_dir / "report" / "photos";
  const cv::Mat a = cv::imread((photos / "a.jpg").string());
  EXPECT_EQ(a.size(), cv::Size(256, 192));
  const cv::Mat d = cv::imread((photos / "d.jpg").string());
  EXPECT_EQ(d.size(), cv::Size(192, 256));
  EXPECT_FALSE(fs::exists(photos / "b.jpg"));
  EXPECT_FALSE(fs::exists(photos / "e.jpg")) << "refused at ingest";
  auto images = ReadIngestedImages(workspace_);
  ASSERT_TRUE(images.ok());
  const std::map<int, std::string> paths = ThumbnailPaths(*images);
  EXPECT_EQ(paths.size(), 4u);
  EXPECT_EQ(paths.at(3), "report/photos/d.jpg");
}

TEST(ExportStage, IsNotResumable) {
  // output/ is rebuilt on every run (see export_stage.h).
  EXPECT_FALSE(ExportStage().Resumable());
  EXPECT_EQ(ExportStage().Name(), "export");
}

}  // namespace
}  // namespace reconduit
