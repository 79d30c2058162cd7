#include "core/io/mesh_ply.h"

#include "core/io/file_util.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

TriangleMesh Tetrahedron(bool normals, bool colors) {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1.5f}};
  if (normals) m.normals.assign(4, Eigen::Vector3f(0, 0.6f, 0.8f));
  if (colors) m.colors = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}, {250, 251, 252}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
  return m;
}

class MeshPlyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mesh_ply_test_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(MeshPlyTest, RoundTripsEveryLayout) {
  for (bool normals : {false, true}) {
    for (bool colors : {false, true}) {
      const TriangleMesh m = Tetrahedron(normals, colors);
      const fs::path path = dir_ / "m.ply";
      ASSERT_TRUE(WriteMeshPly(path, m).ok());
      auto back = ReadMeshPly(path);
      ASSERT_TRUE(back.ok()) << back.status().message();
      EXPECT_EQ(back->positions, m.positions);
      EXPECT_EQ(back->normals, m.normals);
      EXPECT_EQ(back->colors, m.colors);
      EXPECT_EQ(back->faces, m.faces);
    }
  }
}

TEST_F(MeshPlyTest, WritesAHeaderViewersRead) {
  ASSERT_TRUE(WriteMeshPly(dir_ / "m.ply", Tetrahedron(true, true)).ok());
  const std::string bytes = *ReadFile(dir_ / "m.ply");
  EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  EXPECT_NE(bytes.find("element vertex 4\n"), std::string::npos);
  EXPECT_NE(bytes.find("element face 4\nproperty list uchar int vertex_indices\nend_header\n"),
            std::string::npos);
  EXPECT_EQ(bytes.size(), bytes.find("end_header\n") + 11 + 4 * 27 + 4 * 13);
}

TEST_F(MeshPlyTest, RefusesBadMeshesAndFiles) {
  TriangleMesh bad = Tetrahedron(false, true);
  bad.faces.push_back({0, 1, 4});
  EXPECT_EQ(WriteMeshPly(dir_ / "bad.ply", bad).code(), StatusCode::kInvalidArgument);
  bad = Tetrahedron(false, true);
  bad.colors.pop_back();
  EXPECT_EQ(WriteMeshPly(dir_ / "bad.ply", bad).code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(dir_ / "bad.ply"));

  EXPECT_EQ(ReadMeshPly(dir_ / "missing.ply").status().code(), StatusCode::kNotFound);
  ASSERT_TRUE(WriteMeshPly(dir_ / "m.ply", Tetrahedron(true, false)).ok());
  const std::string bytes = *ReadFile(dir_ / "m.ply");
  ASSERT_TRUE(WriteFileAtomically(dir_ / "cut.ply", bytes.substr(0, bytes.size() - 5)).ok());
  EXPECT_EQ(ReadMeshPly(dir_ / "cut.ply").status().code(), StatusCode::kInvalidArgument);
  std::string huge = bytes;
  huge.replace(huge.find("element vertex 4"), 16, "element vertex 99999999999");
  ASSERT_TRUE(WriteFileAtomically(dir_ / "huge.ply", huge).ok());
  EXPECT_EQ(ReadMeshPly(dir_ / "huge.ply").status().code(), StatusCode::kInvalidArgument);
  std::string index = bytes;
  index[index.size() - 4] = 9;  // Last face's last index: 9 of 4 vertices.
  ASSERT_TRUE(WriteFileAtomically(dir_ / "index.ply", index).ok());
  EXPECT_EQ(ReadMeshPly(dir_ / "index.ply").status().code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(WriteFileAtomically(dir_ / "text.ply", "ply\nformat ascii 1.0\nend_header\n").ok());
  EXPECT_EQ(ReadMeshPly(dir_ / "text.ply").status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reconduit
