#include "core/io/file_util.h"

#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/resource.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

class FileUtilTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("reconduit_file_util_" +
            std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST(Sha256, KnownVectors) {
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST_F(FileUtilTest, AtomicWriteCreatesAndReplacesWithoutLeftovers) {
  const fs::path path = dir_ / "report.json";
  ASSERT_TRUE(WriteFileAtomically(path, "first").ok());
  ASSERT_TRUE(WriteFileAtomically(path, "second, longer").ok());
  auto contents = ReadFile(path);
  ASSERT_TRUE(contents.ok());
  EXPECT_EQ(*contents, "second, longer");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1) << "no temporary file is left behind";
}

TEST_F(FileUtilTest, AtomicWriteIntoMissingFolderFails) {
  const Status status = WriteFileAtomically(dir_ / "missing" / "x.txt", "x");
  EXPECT_EQ(status.code(), StatusCode::kInternal);
  EXPECT_NE(status.message().find("cannot create"), std::string::npos) << status;
}

// A full disk, as RLIMIT_FSIZE makes it (write fails with EFBIG once SIGXFSZ is ignored): the
// write fails as kResourceExhausted saying "out of disk space" and naming the file it was for,
// and the earlier version of the file stays, with no temporary file left.
TEST_F(FileUtilTest, AtomicWriteOnAFullDiskSaysSoAndKeepsTheOldFile) {
  const fs::path path = dir_ / "cameras.json";
  ASSERT_TRUE(WriteFileAtomically(path, "old").ok());
  rlimit old_limit{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit small = old_limit;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  const Status status = WriteFileAtomically(path, std::string(100000, 'x'));
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_EQ(status.code(), StatusCode::kResourceExhausted) << status;
  EXPECT_EQ(status.message().rfind("out of disk space: cannot write '" + path.string() + "'", 0),
            0u)
      << status;
  const Result<std::string> contents = ReadFile(path);
  ASSERT_TRUE(contents.ok());
  EXPECT_EQ(*contents, "old");
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1) << "no temporary file is left behind";
}

TEST_F(FileUtilTest, Sha256OfFileMatchesBuffer) {
  std::string big(300000, '\0');
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>(i * 7 + 3);
  ASSERT_TRUE(WriteFileAtomically(dir_ / "big.bin", big).ok());
  auto sha = Sha256OfFile(dir_ / "big.bin");
  ASSERT_TRUE(sha.ok());
  EXPECT_EQ(*sha, Sha256Hex(big));
}

TEST_F(FileUtilTest, MissingFilesAreNotFound) {
  EXPECT_EQ(ReadFile(dir_ / "nope").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(Sha256OfFile(dir_ / "nope").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace reconduit
