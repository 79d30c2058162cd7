#include "core/pipeline/stages/package_stage.h"

#include "core/io/file_util.h"
#include "core/io/reconstruction_json.h"
#include "core/io/zip_test_util.h"
#include "core/pipeline/runner.h"
#include "core/pipeline/stages/ingest_stage.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

TEST(PackageStage, WritesReportManifestAndArchive) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_package_stage_test_" + std::to_string(getpid()));
  fs::remove_all(root);
  Workspace workspace;
  workspace.images = {{"a.jpg", "a.jpg"}, {"b.jpg", "b.jpg"}};
  workspace.work_dir = root / "work";
  workspace.output_dir = root / "output";
  workspace.archive_path = root / "result.zip";
  fs::create_directories(workspace.output_dir);
  ASSERT_TRUE(WriteFileAtomically(workspace.output_dir / "cameras.json", "{}").ok());

  std::vector<std::unique_ptr<Stage>> stages;
  stages.push_back(std::make_unique<PackageStage>());
  const PipelineResult result = RunPipeline(stages, workspace, PipelineOptions(), CancelToken());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;

  auto report = ReadFile(workspace.output_dir / "report.json");
  ASSERT_TRUE(report.ok());
  const auto json = nlohmann::json::parse(*report);
  EXPECT_EQ(json["image_count"], 2);
  EXPECT_EQ(json["options"]["min_image_side"], 100);
  EXPECT_GT(json["peak_memory_bytes"].get<std::int64_t>(), 0);

  ASSERT_TRUE(fs::exists(workspace.archive_path));
  const nlohmann::json& summary = result.stages.back().summary;
  EXPECT_EQ(summary["files"], 4) << "cameras.json, report.html, report.json, manifest.json";
  EXPECT_EQ(summary["archive_sha256"], *Sha256OfFile(workspace.archive_path));
  // The typed hand-off carries the same archive.
  const std::optional<PackageResult>& package = result.stages.back().package;
  ASSERT_TRUE(package.has_value());
  EXPECT_EQ(package->archive_path, workspace.archive_path);
  EXPECT_EQ(package->archive.archive_sha256, *Sha256OfFile(workspace.archive_path));
  EXPECT_EQ(package->archive.archive_bytes,
            static_cast<std::int64_t>(fs::file_size(workspace.archive_path)));
  EXPECT_EQ(package->archive.files.size(), 4u);
  fs::remove_all(root);
}

// A stage before packaging with per-map figures in its summary, as the dense stage has.
class MapsStage : public Stage {
 public:
  std::string_view Name() const override { return "maps"; }
  std::string_view Title() const override { return "Maps"; }
  StageResult Run(StageContext&) const override {
    return StageResult::Success(
        {{"maps", {{{"image", "a.jpg"}, {"seconds", 4.2}, {"depth_fraction", 0.71}}}}});
  }
};

TEST(PackageStage, ReportHasEachStagesTimeOwnPeakProcessPeakAndSummary) {
  const fs::path root =
      fs::temp_directory_path() / ("reconduit_package_stage_report_" + std::to_string(getpid()));
  fs::remove_all(root);
  Workspace workspace;
  workspace.work_dir = root / "work";
  workspace.output_dir = root / "output";

  std::vector<std::unique_ptr<Stage>> stages;
  stages.push_back(std::make_unique<MapsStage>());
  stages.push_back(std::make_unique<PackageStage>());
  const PipelineResult result = RunPipeline(stages, workspace, PipelineOptions(), CancelToken());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;

  const auto json = nlohmann::json::parse(*ReadFile(workspace.output_dir / "report.json"));
  ASSERT_EQ(json["stages"].size(), 1u);
  const nlohmann::json& stage = json["stages"][0];
  const StageRecord& record = result.stages[0];
  EXPECT_EQ(stage["name"], "maps");
  EXPECT_EQ(stage["seconds"].get<double>(), record.seconds);
  EXPECT_GT(stage["peak_memory_bytes"].get<std::int64_t>(), 0);
  EXPECT_EQ(stage["peak_memory_bytes"], record.peak_memory_bytes);
  EXPECT_GT(stage["stage_peak_memory_bytes"].get<std::int64_t>(), 0);
  EXPECT_EQ(stage["stage_peak_memory_bytes"], record.stage_peak_memory_bytes);
  EXPECT_EQ(stage["stage_peak_memory_own"], record.stage_peak_memory_own);
  EXPECT_EQ(stage["summary"]["maps"][0]["image"], "a.jpg");
  EXPECT_EQ(stage["summary"]["maps"][0]["seconds"], 4.2);
  fs::remove_all(root);
}

// A job's output as the export leaves it after the dense stage: two photos (the first
// registered, with its maps and previews; the second refused at ingest, with markup in its
// name), and the ingest records and the model the package stage reads.
class PackageLeanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("reconduit_package_lean_" + std::to_string(getpid()));
    fs::remove_all(root_);
    workspace_.images = {{root_ / "0001.jpg", "a.jpg"}, {root_ / "0002.jpg", "<b>&.jpg"}};
    workspace_.work_dir = root_ / "work";
    workspace_.output_dir = root_ / "output";
    workspace_.archive_path = root_ / "result.zip";
    for (const char* name :
         {"cameras.json", "dense.ply", "depth/a.png", "depth/a.json", "quality/a.png",
          "report/dense/a_depth.jpg", "report/dense/a_quality.png", "report/photos/a.jpg",
          "report/similarity.png"}) {
      fs::create_directories((workspace_.output_dir / name).parent_path());
      ASSERT_TRUE(WriteFileAtomically(workspace_.output_dir / name, name).ok());
    }
    nlohmann::json images = nlohmann::json::array();
    for (int i = 0; i < 2; ++i) {
      IngestedImage image;
      image.index = i;
      image.name = workspace_.images[i].name;
      image.path = workspace_.images[i].path;
      image.photo.accepted = i == 0;
      if (i == 1) image.photo.reason = "not a photo";
      images.push_back(image.ToJson());
    }
    fs::create_directories(workspace_.StageDir("ingest"));
    fs::create_directories(workspace_.StageDir("sparse"));
    ASSERT_TRUE(WriteFileAtomically(workspace_.StageDir("ingest") / "images.json",
                                    nlohmann::json{{"images", images}}.dump())
                    .ok());
    Reconstruction model;
    model.cameras[0] = Camera::FromFocal(640, 480, 600.0);
    model.images[0].image_id = 0;
    model.images[0].camera_id = 0;
    model.images[0].name = "a.jpg";
    ASSERT_TRUE(
        WriteReconstructionJson(workspace_.StageDir("sparse") / "model_0.json", model).ok());
  }
  void TearDown() override { fs::remove_all(root_); }

  PipelineResult Package(const PipelineOptions& options) {
    std::vector<std::unique_ptr<Stage>> stages;
    stages.push_back(std::make_unique<PackageStage>());
    return RunPipeline(stages, workspace_, options, CancelToken());
  }

  // The zip's entries, checked against its manifest: exactly the same files.
  std::map<std::string, std::string> ZipMatchingItsManifest() {
    const auto entries = testing_util::ReadZipEntries(workspace_.archive_path);
    EXPECT_TRUE(entries.count("manifest.json"));
    std::set<std::string> zipped, listed;
    for (const auto& [name, bytes] : entries) {
      if (name != "manifest.json") zipped.insert(name);
    }
    const nlohmann::json manifest = nlohmann::json::parse(entries.at("manifest.json"));
    for (const auto& file : manifest["files"]) listed.insert(file["name"].get<std::string>());
    EXPECT_EQ(zipped, listed);
    return entries;
  }

  // Every picture and link of report.html, as paths inside the archive.
  static std::set<std::string> References(const std::string& html) {
    std::set<std::string> targets;
    const std::regex reference("(src|href)=\"\\./([^\"]*)\"");
    for (auto it = std::sregex_iterator(html.begin(), html.end(), reference);
         it != std::sregex_iterator(); ++it)
      targets.insert((*it)[2].str());
    return targets;
  }

  fs::path root_;
  Workspace workspace_;
};

TEST_F(PackageLeanTest, LeavesTheDenseFilesOutOfTheZipAndItsReport) {
  PipelineOptions options;
  options.package_dense_files = false;
  const PipelineResult result = Package(options);
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  const auto entries = ZipMatchingItsManifest();
  for (const char* name : {"dense.ply", "depth/a.png", "depth/a.json", "quality/a.png"}) {
    EXPECT_FALSE(entries.count(name)) << name;
    EXPECT_TRUE(fs::exists(workspace_.output_dir / name)) << name << ": still served";
  }
  for (const char* name : {"cameras.json", "report.json", "report.html", "report/dense/a_depth.jpg",
                           "report/photos/a.jpg"})
    EXPECT_TRUE(entries.count(name)) << name;
  EXPECT_EQ(result.stages.back().summary["left_out"],
            (nlohmann::json{"dense.ply", "depth/", "quality/"}));

  // report.html references only what the zip holds, and says what was left out.
  const std::string& html = entries.at("report.html");
  const std::set<std::string> references = References(html);
  for (const std::string& target : references) EXPECT_TRUE(entries.count(target)) << target;
  EXPECT_TRUE(references.count("report/photos/a.jpg"));
  EXPECT_TRUE(references.count("report/dense/a_depth.jpg"));
  EXPECT_FALSE(references.count("depth/a.png"));
  EXPECT_NE(html.find("Left out of this archive (option package_dense_files): dense.ply, depth/, "
                      "quality/"),
            std::string::npos);
  EXPECT_NE(html.find("&lt;b&gt;&amp;.jpg"), std::string::npos) << "the refused photo, escaped";
  EXPECT_EQ(html.find("<b>&.jpg"), std::string::npos);
}

TEST_F(PackageLeanTest, PacksTheDenseFilesByDefault) {
  const PipelineResult result = Package(PipelineOptions());
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  const auto entries = ZipMatchingItsManifest();
  for (const char* name : {"dense.ply", "depth/a.png", "depth/a.json", "quality/a.png"})
    EXPECT_TRUE(entries.count(name)) << name;
  EXPECT_FALSE(result.stages.back().summary.contains("left_out"));
  const std::string& html = entries.at("report.html");
  const std::set<std::string> references = References(html);
  for (const std::string& target : references) EXPECT_TRUE(entries.count(target)) << target;
  EXPECT_TRUE(references.count("depth/a.png"));
  EXPECT_TRUE(references.count("dense.ply"));
  EXPECT_EQ(html.find("Left out"), std::string::npos);
}

// Without an archive (the command line) the folder is the result: nothing is left out.
TEST_F(PackageLeanTest, TheCommandLinesFolderKeepsEverything) {
  workspace_.archive_path.clear();
  PipelineOptions options;
  options.package_dense_files = false;
  const PipelineResult result = Package(options);
  ASSERT_EQ(result.status, StageStatus::kSuccess) << result.message;
  auto html = ReadFile(workspace_.output_dir / "report.html");
  ASSERT_TRUE(html.ok());
  EXPECT_TRUE(References(*html).count("depth/a.png"));
  EXPECT_FALSE(References(*html).count("manifest.json")) << "no manifest without a zip";
}

}  // namespace
}  // namespace reconduit
