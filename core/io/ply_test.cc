#include "core/io/ply.h"

#include "core/io/file_util.h"
#include "core/io/sparse_model_test_util.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using testing_util::DistortedSceneOptions;
using testing_util::FreshTestFolder;
using testing_util::SyntheticReconstruction;

// Little-endian decoding, independent of the host's byte order.
std::uint64_t LittleEndian(const std::string& bytes, std::size_t offset, int size) {
  std::uint64_t v = 0;
  for (int i = size - 1; i >= 0; --i) {
    v = (v << 8) | static_cast<unsigned char>(bytes.at(offset + i));
  }
  return v;
}
float FloatAt(const std::string& bytes, std::size_t offset) {
  const auto bits = static_cast<std::uint32_t>(LittleEndian(bytes, offset, 4));
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}
double DoubleAt(const std::string& bytes, std::size_t offset) {
  const std::uint64_t bits = LittleEndian(bytes, offset, 8);
  double d;
  std::memcpy(&d, &bits, 8);
  return d;
}

PointCloud TestCloud() {
  PointCloud cloud;
  cloud.positions = {{1.5, -2.25, 3.0}, {0.1, 1e6, -7.125}, {-0.0, 42.0, 1.0 / 3.0}};
  cloud.colors = {{255, 0, 1}, {12, 34, 56}, {0, 128, 255}};
  return cloud;
}

class PlyTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = FreshTestFolder(); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(PlyTest, FloatPositionsAndColours) {
  const PointCloud cloud = TestCloud();
  ASSERT_TRUE(WritePointCloudPly(dir_ / "sparse.ply", cloud).ok());
  const std::string bytes = *ReadFile(dir_ / "sparse.ply");
  const std::string header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment Reconduit point cloud\n"
      "element vertex 3\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "end_header\n";
  ASSERT_EQ(bytes.substr(0, header.size()), header);
  constexpr std::size_t kStride = 3 * 4 + 3;
  ASSERT_EQ(bytes.size(), header.size() + 3 * kStride);
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t at = header.size() + i * kStride;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(FloatAt(bytes, at + 4 * k), static_cast<float>(cloud.positions[i][k]))
          << "point " << i << " axis " << k;
      EXPECT_EQ(static_cast<unsigned char>(bytes[at + 12 + k]), cloud.colors[i][k]);
    }
  }
  // No temporary file is left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1);
}

TEST_F(PlyTest, DoublePositionsAndNormals) {
  PointCloud cloud = TestCloud();
  cloud.normals = {{0, 0, 1}, {0.6f, 0.8f, 0}, {-1, 0, 0}};
  PlyOptions options;
  options.double_precision = true;
  ASSERT_TRUE(WritePointCloudPly(dir_ / "dense.ply", cloud, options).ok());
  const std::string bytes = *ReadFile(dir_ / "dense.ply");
  const std::string header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment Reconduit point cloud\n"
      "element vertex 3\n"
      "property double x\n"
      "property double y\n"
      "property double z\n"
      "property float nx\n"
      "property float ny\n"
      "property float nz\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "end_header\n";
  ASSERT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_EQ(PointCloudPlyHeader(3, true, options), header);
  constexpr std::size_t kStride = 3 * 8 + 3 * 4 + 3;
  ASSERT_EQ(bytes.size(), header.size() + 3 * kStride);
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t at = header.size() + i * kStride;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(DoubleAt(bytes, at + 8 * k), cloud.positions[i][k]);
      EXPECT_EQ(FloatAt(bytes, at + 24 + 4 * k), cloud.normals[i][k]);
      EXPECT_EQ(static_cast<unsigned char>(bytes[at + 36 + k]), cloud.colors[i][k]);
    }
  }
}

TEST_F(PlyTest, SparseCloudFromReconstruction) {
  const Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  const PointCloud cloud = PointCloudFromReconstruction(rec);
  ASSERT_EQ(cloud.positions.size(), rec.points.size());
  ASSERT_EQ(cloud.colors.size(), rec.points.size());
  EXPECT_TRUE(cloud.normals.empty());
  EXPECT_EQ(cloud.positions.front(), rec.points.begin()->second.xyz_in_world);
  EXPECT_EQ(cloud.colors.back(), rec.points.rbegin()->second.rgb);
  ASSERT_TRUE(WritePointCloudPly(dir_ / "sparse.ply", cloud).ok());
  EXPECT_EQ(fs::file_size(dir_ / "sparse.ply"),
            PointCloudPlyHeader(rec.points.size(), false).size() + 15 * rec.points.size());
}

TEST_F(PlyTest, EmptyCloudIsAValidFile) {
  ASSERT_TRUE(WritePointCloudPly(dir_ / "empty.ply", PointCloud()).ok());
  EXPECT_EQ(*ReadFile(dir_ / "empty.ply"), PointCloudPlyHeader(0, false));
}

TEST_F(PlyTest, MismatchedArraysAreRefused) {
  PointCloud cloud = TestCloud();
  cloud.colors.pop_back();
  EXPECT_EQ(WritePointCloudPly(dir_ / "bad.ply", cloud).code(), StatusCode::kInvalidArgument);
  cloud = TestCloud();
  cloud.normals = {{0, 0, 1}};
  EXPECT_EQ(WritePointCloudPly(dir_ / "bad.ply", cloud).code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(dir_ / "bad.ply"));
}

TEST_F(PlyTest, UnwritableFolderIsAnError) {
  EXPECT_EQ(WritePointCloudPly(dir_ / "missing" / "x.ply", TestCloud()).code(),
            StatusCode::kInternal);
}

}  // namespace
}  // namespace reconduit
