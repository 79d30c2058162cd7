#include "core/io/result_archive.h"

#include "core/io/file_util.h"
#include "core/io/zip_test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

class ResultArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            (std::string("reconduit_archive_") +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "out" / "sparse");
    ASSERT_TRUE(WriteFileAtomically(root_ / "out" / "report.json", "{\"ok\":true}\n").ok());
    ASSERT_TRUE(WriteFileAtomically(root_ / "out" / "sparse" / "cameras.txt", "# cams\n").ok());
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path root_;
};

TEST_F(ResultArchiveTest, PacksEveryFileWithAVerifiableManifest) {
  fs::create_symlink("/etc/passwd", root_ / "out" / "link");
  auto summary = WriteResultArchive(root_ / "out", root_ / "result.zip", CancelToken());
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_FALSE(fs::exists(root_ / "result.zip.tmp"));

  const auto entries = testing_util::ReadZipEntries(root_ / "result.zip");
  ASSERT_EQ(entries.size(), 3u) << "report, cameras, manifest; never the symlink";
  EXPECT_EQ(entries.at("sparse/cameras.txt"), "# cams\n");
  const auto manifest = nlohmann::json::parse(entries.at("manifest.json"));
  ASSERT_EQ(manifest["files"].size(), 2u);
  for (const auto& file : manifest["files"]) {
    const std::string& data = entries.at(file["name"].get<std::string>());
    EXPECT_EQ(file["bytes"].get<std::int64_t>(), static_cast<std::int64_t>(data.size()));
    EXPECT_EQ(file["sha256"].get<std::string>(), Sha256Hex(data));
  }
  EXPECT_EQ(summary->archive_bytes, static_cast<std::int64_t>(fs::file_size(root_ / "result.zip")));
  EXPECT_EQ(summary->archive_sha256, *Sha256OfFile(root_ / "result.zip"));
  EXPECT_EQ(summary->files.back().name, "manifest.json");
}

TEST_F(ResultArchiveTest, RewritingReplacesTheArchive) {
  ASSERT_TRUE(WriteResultArchive(root_ / "out", root_ / "result.zip", CancelToken()).ok());
  ASSERT_TRUE(WriteFileAtomically(root_ / "out" / "extra.txt", "more").ok());
  ASSERT_TRUE(WriteResultArchive(root_ / "out", root_ / "result.zip", CancelToken()).ok());
  EXPECT_EQ(testing_util::ReadZipEntries(root_ / "result.zip").count("extra.txt"), 1u);
}

// The lean archive: a folder entry leaves out everything under it, a file entry that file
// only (not a file whose name merely starts with it); the manifest lists exactly the zip.
TEST_F(ResultArchiveTest, LeavesOutExcludedFilesAndFoldersFromZipAndManifest) {
  fs::create_directories(root_ / "out" / "depth");
  fs::create_directories(root_ / "out" / "report" / "dense");
  for (const char* name :
       {"depth/a.png", "depth/a.json", "dense.ply", "dense.ply.txt", "report/dense/a_depth.jpg"})
    ASSERT_TRUE(WriteFileAtomically(root_ / "out" / name, name).ok());
  const ArchiveExclusions excluded = {"depth/", "dense.ply", "quality/"};
  auto listed = ListResultFiles(root_ / "out", excluded);
  ASSERT_TRUE(listed.ok()) << listed.status();
  const std::vector<std::string> expected = {"dense.ply.txt", "report.json",
                                             "report/dense/a_depth.jpg", "sparse/cameras.txt"};
  EXPECT_EQ(*listed, expected);

  auto summary = WriteResultArchive(root_ / "out", root_ / "result.zip", CancelToken(), excluded);
  ASSERT_TRUE(summary.ok()) << summary.status();
  const auto entries = testing_util::ReadZipEntries(root_ / "result.zip");
  std::vector<std::string> zipped;
  for (const auto& [name, data] : entries) zipped.push_back(name);
  std::vector<std::string> with_manifest = expected;
  with_manifest.push_back("manifest.json");
  std::sort(with_manifest.begin(), with_manifest.end());
  EXPECT_EQ(zipped, with_manifest);
  std::vector<std::string> manifested;
  const nlohmann::json manifest = nlohmann::json::parse(entries.at("manifest.json"));
  for (const auto& file : manifest["files"]) manifested.push_back(file["name"]);
  EXPECT_EQ(manifested, expected) << "the manifest lists what the zip holds, itself aside";
  // Left out of the zip, not deleted: the service still serves them one by one.
  EXPECT_TRUE(fs::exists(root_ / "out" / "depth" / "a.png"));
  EXPECT_TRUE(fs::exists(root_ / "out" / "dense.ply"));
}

TEST_F(ResultArchiveTest, MissingFolderIsNotFound) {
  auto summary = WriteResultArchive(root_ / "nope", root_ / "result.zip", CancelToken());
  EXPECT_EQ(summary.status().code(), StatusCode::kNotFound);
}

TEST_F(ResultArchiveTest, CanceledLeavesNoArchive) {
  CancelToken cancel;
  cancel.RequestCancel();
  EXPECT_THROW((void)WriteResultArchive(root_ / "out", root_ / "result.zip", cancel),
               CanceledError);
  EXPECT_FALSE(fs::exists(root_ / "result.zip"));
  EXPECT_FALSE(fs::exists(root_ / "result.zip.tmp"));
}

}  // namespace
}  // namespace reconduit
