#include "core/pipeline/stages/package_stage.h"

#include "core/io/file_util.h"
#include "core/pipeline/runner.h"

#include <gtest/gtest.h>

#include <filesystem>
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
  EXPECT_EQ(summary["files"], 3) << "cameras.json, report.json, manifest.json";
  EXPECT_EQ(summary["archive_sha256"], *Sha256OfFile(workspace.archive_path));
  // The typed hand-off carries the same archive.
  const std::optional<PackageResult>& package = result.stages.back().package;
  ASSERT_TRUE(package.has_value());
  EXPECT_EQ(package->archive_path, workspace.archive_path);
  EXPECT_EQ(package->archive.archive_sha256, *Sha256OfFile(workspace.archive_path));
  EXPECT_EQ(package->archive.archive_bytes,
            static_cast<std::int64_t>(fs::file_size(workspace.archive_path)));
  EXPECT_EQ(package->archive.files.size(), 3u);
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

}  // namespace
}  // namespace reconduit
