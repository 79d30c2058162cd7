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

}  // namespace
}  // namespace reconduit
