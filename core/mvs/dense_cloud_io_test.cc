#include "core/mvs/dense_cloud_io.h"

#include "core/io/file_util.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

DenseCloud ThreePoints() {
  DenseCloud cloud;
  cloud.positions = {{1, 2, 3}, {-4.5f, 0, 1e6f}, {0, 0, 0}};
  cloud.normals = {{0, 0, -1}, {1, 0, 0}, {0, 1, 0}};
  cloud.colors = {{255, 0, 7}, {1, 2, 3}, {9, 9, 9}};
  cloud.visibility = {0, 4, 2, 3, 7, 10, 11};
  cloud.visibility_offsets = {0, 2, 2, 7};  // The second point lists no photo.
  return cloud;
}

class DenseCloudIoTest : public ::testing::Test {
 protected:
  fs::path path_ = fs::temp_directory_path() / "reconduit_dense_cloud_io_test.ply";
  void TearDown() override { fs::remove(path_); }
};

TEST_F(DenseCloudIoTest, RoundTripIsExact) {
  const DenseCloud cloud = ThreePoints();
  ASSERT_TRUE(WriteDenseCloudPly(path_, cloud).ok());
  auto read = ReadDenseCloudPly(path_);
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read->positions, cloud.positions);
  EXPECT_EQ(read->normals, cloud.normals);
  EXPECT_EQ(read->colors, cloud.colors);
  EXPECT_EQ(read->visibility, cloud.visibility);
  EXPECT_EQ(read->visibility_offsets, cloud.visibility_offsets);
}

TEST_F(DenseCloudIoTest, HeaderIsStandardPlyWithAVisibilityList) {
  ASSERT_TRUE(WriteDenseCloudPly(path_, ThreePoints()).ok());
  const std::string text = *ReadFile(path_);
  EXPECT_EQ(text.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(text.find("element vertex 3\n"), std::string::npos);
  EXPECT_NE(text.find("property list uchar int visibility\nend_header\n"), std::string::npos);
  // 3 points x (6 floats + 3 colour bytes + 1 count byte) + 7 ids x 4 bytes after the header.
  EXPECT_EQ(text.size() - (text.find("end_header\n") + 11), 3u * 28u + 7u * 4u);
}

TEST_F(DenseCloudIoTest, EmptyCloud) {
  ASSERT_TRUE(WriteDenseCloudPly(path_, DenseCloud()).ok());
  auto read = ReadDenseCloudPly(path_);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->size(), 0u);
  EXPECT_EQ(read->visibility_offsets.size(), 1u);
}

TEST_F(DenseCloudIoTest, RefusesInconsistentCloudsAndDamagedFiles) {
  DenseCloud bad = ThreePoints();
  bad.normals.pop_back();
  EXPECT_EQ(WriteDenseCloudPly(path_, bad).code(), StatusCode::kInvalidArgument);

  ASSERT_TRUE(WriteDenseCloudPly(path_, ThreePoints()).ok());
  const std::string text = *ReadFile(path_);
  ASSERT_TRUE(WriteFileAtomically(path_, text.substr(0, text.size() - 3)).ok());
  EXPECT_EQ(ReadDenseCloudPly(path_).status().code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(WriteFileAtomically(path_, text + "x").ok());
  EXPECT_EQ(ReadDenseCloudPly(path_).status().code(), StatusCode::kInvalidArgument);
  std::string other = text;
  other.replace(other.find("element vertex 3"), 16, "element vertex 9");
  ASSERT_TRUE(WriteFileAtomically(path_, other).ok());
  EXPECT_EQ(ReadDenseCloudPly(path_).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadDenseCloudPly(path_.string() + ".missing").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace reconduit
