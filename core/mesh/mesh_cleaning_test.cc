#include "core/mesh/mesh_cleaning.h"

#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>

namespace reconduit {
namespace {

// An n x n grid of unit squares on z = 0 (two faces each, counter-clockwise seen from +z),
// offset by `origin`.
void AddGrid(int n, const Eigen::Vector3f& origin, TriangleMesh* mesh) {
  const int base = static_cast<int>(mesh->positions.size());
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      mesh->positions.push_back(origin + Eigen::Vector3f(i, j, 0));
      mesh->colors.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(j), 0});
    }
  }
  auto at = [&](int i, int j) { return base + j * (n + 1) + i; };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh->faces.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      mesh->faces.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
}

TEST(CleanMesh, KeepsACleanGridAsItIs) {
  TriangleMesh mesh;
  AddGrid(10, Eigen::Vector3f::Zero(), &mesh);
  const TriangleMesh before = mesh;
  const CleaningSummary s = CleanMesh(&mesh);
  EXPECT_EQ(mesh.faces, before.faces);
  EXPECT_EQ(mesh.positions, before.positions);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.degenerate_faces + s.duplicate_faces + s.non_manifold_faces, 0u);
}

TEST(CleanMesh, RemovesDegenerateAndDuplicateFaces) {
  TriangleMesh mesh;
  AddGrid(4, Eigen::Vector3f::Zero(), &mesh);
  const std::size_t faces = mesh.NumFaces();
  mesh.faces.emplace_back(0, 0, 1);     // Repeated vertex.
  mesh.faces.emplace_back(0, 1, 2);     // Collinear: zero area.
  mesh.faces.push_back(mesh.faces[3]);  // Same face again.
  const Eigen::Vector3i f = mesh.faces[5];
  mesh.faces.emplace_back(f[1], f[2], f[0]);  // Same, rotated.
  const CleaningSummary s = CleanMesh(&mesh);
  EXPECT_EQ(s.degenerate_faces, 2u);
  EXPECT_EQ(s.duplicate_faces, 2u);
  EXPECT_EQ(mesh.NumFaces(), faces);
}

TEST(CleanMesh, OppositeTwinsGoBoth) {
  TriangleMesh mesh;
  AddGrid(4, Eigen::Vector3f::Zero(), &mesh);
  const Eigen::Vector3i f = mesh.faces[0];
  mesh.faces.emplace_back(f[0], f[2], f[1]);
  const CleaningSummary s = CleanMesh(&mesh);
  EXPECT_EQ(s.duplicate_faces, 2u);
  EXPECT_EQ(mesh.NumFaces(), 31u);
}

TEST(CleanMesh, RemovesFacesAtNonManifoldEdgesAndSmallPieces) {
  TriangleMesh mesh;
  AddGrid(20, Eigen::Vector3f::Zero(), &mesh);
  // A fin standing on the diagonal of square (5, 5), between vertices 110 = (5, 5) and
  // 132 = (6, 6), which two grid faces share: three faces on that edge.
  mesh.positions.push_back({5.5f, 5.5f, 1.0f});
  mesh.colors.push_back({0, 0, 0});
  mesh.faces.emplace_back(110, 132, static_cast<int>(mesh.positions.size()) - 1);
  AddGrid(1, Eigen::Vector3f(50, 0, 0), &mesh);  // A floating piece of 2 faces (0.25 %).
  const CleaningSummary s = CleanMesh(&mesh);
  EXPECT_EQ(s.non_manifold_faces, 3u);  // The fin and the grid's two faces on that edge.
  EXPECT_EQ(s.removed_components, 1u);
  EXPECT_EQ(s.small_component_faces, 2u);
  EXPECT_EQ(mesh.NumFaces(), 800u - 2);
  EXPECT_EQ(mesh.NumVertices(), 21u * 21u);  // Fin tip and the piece's vertices are gone.
  EXPECT_EQ(mesh.colors.size(), mesh.NumVertices());
  for (const Eigen::Vector3f& p : mesh.positions) EXPECT_LT(p.x(), 21);
}

TEST(CleanMesh, RejectsBadIndicesAndTexturedMeshes) {
  TriangleMesh mesh;
  AddGrid(2, Eigen::Vector3f::Zero(), &mesh);
  mesh.faces.emplace_back(0, 1, 99);
  EXPECT_THROW(CleanMesh(&mesh), CheckError);
  mesh.faces.pop_back();
  mesh.texcoords.assign(3 * mesh.NumFaces(), Eigen::Vector2f::Zero());
  EXPECT_THROW(CleanMesh(&mesh), CheckError);
}

TEST(SimplifyMesh, ReachesTheTargetAndKeepsAFlatGridFlatAndItsOutline) {
  TriangleMesh mesh;
  AddGrid(60, Eigen::Vector3f::Zero(), &mesh);
  const SimplificationSummary s = SimplifyMesh(&mesh, 500);
  EXPECT_EQ(s.faces_before, 7200u);
  EXPECT_LE(s.faces_after, 500u);
  EXPECT_EQ(mesh.NumFaces(), s.faces_after);
  EXPECT_EQ(mesh.colors.size(), mesh.NumVertices());
  double area = 0;
  for (const Eigen::Vector3i& t : mesh.faces) {
    const Eigen::Vector3f n = (mesh.positions[t[1]] - mesh.positions[t[0]])
                                  .cross(mesh.positions[t[2]] - mesh.positions[t[0]]);
    EXPECT_GT(n.z(), 0);
    area += 0.5 * n.norm();
  }
  EXPECT_NEAR(area, 3600, 1e-2);  // Borders locked: the outline is kept exactly.
  for (const Eigen::Vector3f& p : mesh.positions) EXPECT_EQ(p.z(), 0.0f);
}

TEST(SimplifyMesh, KeepsDetailWhereTheSurfaceBends) {
  // A flat grid with a ridge along x = 30: the ridge keeps its vertices, the flat parts lose them.
  TriangleMesh mesh;
  AddGrid(60, Eigen::Vector3f::Zero(), &mesh);
  for (Eigen::Vector3f& p : mesh.positions) p.z() = std::exp(-std::pow(p.x() - 30, 2) / 8.0f);
  SimplifyMesh(&mesh, 1500);
  int near_ridge = 0, far = 0;
  for (const Eigen::Vector3f& p : mesh.positions) {
    if (std::abs(p.x() - 30) < 6) ++near_ridge;
    if (std::abs(p.x() - 30) > 20) ++far;
  }
  // The ridge band is 12 of 60 columns, the far bands 20: the band gets more vertices.
  EXPECT_GT(near_ridge, 2 * far);
}

TEST(SimplifyMesh, LeavesSmallMeshesAlone) {
  TriangleMesh mesh;
  AddGrid(3, Eigen::Vector3f::Zero(), &mesh);
  const TriangleMesh before = mesh;
  SimplifyMesh(&mesh, 100);
  EXPECT_EQ(mesh.faces, before.faces);
}

TEST(ComputeVertexNormals, PlaneAndUnusedVertex) {
  TriangleMesh mesh;
  AddGrid(3, Eigen::Vector3f::Zero(), &mesh);
  mesh.positions.push_back({9, 9, 9});
  ComputeVertexNormals(&mesh);
  ASSERT_EQ(mesh.normals.size(), mesh.NumVertices());
  for (std::size_t v = 0; v + 1 < mesh.NumVertices(); ++v)
    EXPECT_TRUE(mesh.normals[v].isApprox(Eigen::Vector3f::UnitZ())) << v;
  EXPECT_EQ(mesh.normals.back(), Eigen::Vector3f::Zero());
  mesh.colors.push_back({1, 2, 3});
  EXPECT_EQ(RemoveUnusedVertices(&mesh), 1u);
  EXPECT_EQ(mesh.normals.size(), 16u);
}

}  // namespace
}  // namespace reconduit
