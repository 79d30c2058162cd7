#include "core/texture/face_labeling.h"

#include "core/texture/texture_test_util.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

namespace reconduit {
namespace {

using texture_test::AppendQuad;
using texture_test::CameraAt;
using texture_test::Panel;
using texture_test::TestCamera;
using texture_test::Wall;

// Views without photos (the labelling never loads them).
std::vector<TextureView> Views(const std::vector<double>& xs) {
  std::vector<TextureView> views;
  for (const double x : xs) {
    views.push_back(
        texture_test::MakeView("x" + std::to_string(x), TestCamera(), CameraAt(x), cv::Mat()));
  }
  return views;
}

TEST(FaceAdjacency, GridFacesShareEdges) {
  TriangleMesh mesh;
  AppendQuad(Wall(), 4, 3, false, &mesh);
  const FaceAdjacency adjacency = ComputeFaceAdjacency(mesh);
  ASSERT_EQ(adjacency.offsets.size(), mesh.faces.size() + 1);
  // 4 x 3 cells, 2 triangles each: interior edges = 3 per cell (diagonal, right, top) minus
  // the borders: 12 diagonals + 3 * 3 vertical + 4 * 2 horizontal = 29, each listed twice.
  EXPECT_EQ(adjacency.neighbors.size(), 2u * 29u);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int degree = adjacency.offsets[f + 1] - adjacency.offsets[f];
    EXPECT_GE(degree, 1);
    EXPECT_LE(degree, 3);
  }
}

// A face labelled with a view must be seen whole by that view: the ray from the camera
// centre to its centroid meets the wall at the centroid, not the panel in front of it.
TEST(ComputeFaceCandidates, OccludedFacesAreNotCandidates) {
  TriangleMesh mesh;
  AppendQuad(Wall(), 80, 40, false, &mesh);
  const int num_wall_faces = static_cast<int>(mesh.faces.size());
  AppendQuad(Panel(), 10, 10, false, &mesh);
  TexturedScene scene;
  scene.quads = {Wall(), Panel()};
  const std::vector<TextureView> views = Views({-2.0, 0.0, 2.0});
  const FaceCandidates candidates =
      ComputeFaceCandidates(mesh, views, TextureOptions(), nullptr, CancelToken());

  int hidden_somewhere = 0, checked = 0;
  for (int f = 0; f < num_wall_faces; ++f) {
    const Eigen::Vector3i& face = mesh.faces[f];
    const Eigen::Vector3d centroid =
        (mesh.positions[face[0]] + mesh.positions[face[1]] + mesh.positions[face[2]])
            .cast<double>() /
        3.0;
    std::set<int> seen;
    for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
      seen.insert(candidates.items[i].view);
    }
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector3d center = views[v].cam_from_world.CenterInWorld();
      const auto hit = IntersectRay(scene, center, centroid - center);
      ASSERT_TRUE(hit.has_value());
      const bool truly_visible = hit->quad == 0 && (hit->point - centroid).norm() < 1e-6;
      if (seen.count(v)) {
        EXPECT_TRUE(truly_visible) << "face " << f << " is a candidate of hidden view " << v;
        ++checked;
      }
      // Faces well inside the panel's shadow (their corners hidden too) must be rejected;
      // near the shadow's border a face is partly visible and may go either way.
      if (!truly_visible) ++hidden_somewhere;
    }
  }
  EXPECT_GT(hidden_somewhere, 500);  // The panel hides ~13 % of the wall from each view.
  EXPECT_GT(checked, 2 * num_wall_faces);
  // The panel's faces are seen by all three.
  for (int f = num_wall_faces; f < static_cast<int>(mesh.faces.size()); ++f) {
    EXPECT_EQ(candidates.NumCandidates(f), 3);
  }
}

TEST(ComputeFaceCandidates, BackFacingAndOutsideFacesAreNotCandidates) {
  TriangleMesh mesh;
  AppendQuad(Wall(), 8, 4, true, &mesh);  // Facing away from the cameras.
  const std::vector<TextureView> views = Views({-2.0, 0.0, 2.0});
  FaceCandidates candidates =
      ComputeFaceCandidates(mesh, views, TextureOptions(), nullptr, CancelToken());
  EXPECT_TRUE(candidates.items.empty());
  EXPECT_EQ(SelectBestViews(candidates), std::vector<int>(mesh.faces.size(), -1));

  TriangleMesh far;  // A wall far to the side: outside every photo.
  TexturedQuad side = Wall();
  side.origin += Eigen::Vector3d(40, 0, 0);
  AppendQuad(side, 4, 2, false, &far);
  EXPECT_TRUE(
      ComputeFaceCandidates(far, views, TextureOptions(), nullptr, CancelToken()).items.empty());
}

// A wall whose vertices are jittered along its normal: every face's best view depends on its
// own small tilt, so the greedy labelling is fragmented; smoothing makes few large charts.
TEST(SmoothLabels, ReducesTheNumberOfCharts) {
  TriangleMesh mesh;
  AppendQuad(Wall(), 60, 30, false, &mesh);
  std::mt19937 rng(3);
  std::normal_distribution<float> jitter(0.0f, 0.01f);
  for (Eigen::Vector3f& p : mesh.positions) p.y() += jitter(rng);
  const std::vector<TextureView> views = Views({-1.0, -0.5, 0.0, 0.5, 1.0});
  const FaceCandidates candidates =
      ComputeFaceCandidates(mesh, views, TextureOptions(), nullptr, CancelToken());
  const FaceAdjacency adjacency = ComputeFaceAdjacency(mesh);
  std::vector<int> labels = SelectBestViews(candidates);
  const std::vector<int> greedy = labels;
  const int greedy_charts = static_cast<int>(ComputeCharts(labels, adjacency).chart_view.size());

  const auto energy = [&](const std::vector<int>& l, double weight) {
    double e = 0.0;
    for (std::size_t f = 0; f < l.size(); ++f) {
      float best = 0.0f, mine = 0.0f;
      for (int i = candidates.offsets[f]; i < candidates.offsets[f + 1]; ++i) {
        best = std::max(best, candidates.items[i].quality);
        if (candidates.items[i].view == l[f]) mine = candidates.items[i].quality;
      }
      e += 1.0 - mine / best;
      for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
        if (l[adjacency.neighbors[n]] != l[f]) e += 0.5 * weight;  // Each pair counted twice.
      }
    }
    return e;
  };
  const int sweeps = SmoothLabels(candidates, adjacency, 0.5, 50, &labels);
  const Charts charts = ComputeCharts(labels, adjacency);
  const int smoothed_charts = static_cast<int>(charts.chart_view.size());
  std::printf("%zu faces: %d charts greedy, %d after %d sweeps; energy %.1f -> %.1f\n",
              mesh.faces.size(), greedy_charts, smoothed_charts, sweeps, energy(greedy, 0.5),
              energy(labels, 0.5));
  EXPECT_GT(greedy_charts, 100);
  EXPECT_LT(smoothed_charts * 10, greedy_charts);
  EXPECT_LT(energy(labels, 0.5), energy(greedy, 0.5));
  EXPECT_LT(sweeps, 50);  // Converged.
  // Charts partition the labelled faces.
  int total = 0;
  for (std::size_t c = 0; c < charts.chart_faces.size(); ++c) {
    for (const int f : charts.chart_faces[c]) {
      EXPECT_EQ(charts.face_chart[f], static_cast<int>(c));
      EXPECT_EQ(labels[f], charts.chart_view[c]);
    }
    total += static_cast<int>(charts.chart_faces[c].size());
  }
  EXPECT_EQ(total, static_cast<int>(mesh.faces.size()));
  // Weight 0 leaves the greedy labelling.
  std::vector<int> unchanged = greedy;
  SmoothLabels(candidates, adjacency, 0.0, 50, &unchanged);
  EXPECT_EQ(unchanged, greedy);
}

TEST(ComputeFaceCandidates, HonoursCancellation) {
  TriangleMesh mesh;
  AppendQuad(Wall(), 8, 4, false, &mesh);
  CancelToken cancel;
  cancel.RequestCancel();
  EXPECT_THROW(ComputeFaceCandidates(mesh, Views({0.0}), TextureOptions(), nullptr, cancel),
               CanceledError);
}

}  // namespace
}  // namespace reconduit
