#include "core/texture/seam_blending.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace reconduit::texture_internal {
namespace {

// A flat grid of kN x kN vertices; the faces of columns < kSplit form chart 0, the others
// chart 1. Each chart's faces are mapped, with the grid's layout, into their own half of one
// 512 x 256 page (kScale texels per grid step), filled with a uniform colour per chart.
constexpr int kN = 9, kSplit = 4, kScale = 24;

struct TwoCharts {
  TriangleMesh mesh;
  std::vector<int> face_chart;
};

Eigen::Vector2f Uv(int i, int j, int chart) {
  return {(chart * 256 + 8 + i * kScale + 0.5f) / 512.0f, (8 + j * kScale + 0.5f) / 256.0f};
}

TwoCharts MakeTwoCharts(const cv::Scalar& left, const cv::Scalar& right) {
  TwoCharts t;
  for (int j = 0; j < kN; ++j) {
    for (int i = 0; i < kN; ++i) t.mesh.positions.emplace_back(i, j, 0.0f);
  }
  const auto at = [](int i, int j) { return j * kN + i; };
  for (int j = 0; j + 1 < kN; ++j) {
    for (int i = 0; i + 1 < kN; ++i) {
      const int chart = i < kSplit ? 0 : 1;
      const int corners[2][3][2] = {{{i, j}, {i + 1, j}, {i + 1, j + 1}},
                                    {{i, j}, {i + 1, j + 1}, {i, j + 1}}};
      for (const auto& tri : corners) {
        t.mesh.faces.emplace_back(at(tri[0][0], tri[0][1]), at(tri[1][0], tri[1][1]),
                                  at(tri[2][0], tri[2][1]));
        for (const auto& corner : tri) t.mesh.texcoords.push_back(Uv(corner[0], corner[1], chart));
        t.mesh.face_pages.push_back(0);
        t.face_chart.push_back(chart);
      }
    }
  }
  cv::Mat page(256, 512, CV_8UC3);
  page(cv::Rect(0, 0, 256, 256)).setTo(left);
  page(cv::Rect(256, 0, 256, 256)).setTo(right);
  t.mesh.texture_pages.push_back(page);
  return t;
}

cv::Vec3b TexelAt(const TriangleMesh& mesh, int i, int j, int chart) {
  const Eigen::Vector2f uv = Uv(i, j, chart);
  return mesh.texture_pages[0].at<cv::Vec3b>(static_cast<int>(uv.y() * 256),
                                             static_cast<int>(uv.x() * 512));
}

TEST(BlendSeams, MeetsInTheMiddleAtTheBorderAndFadesIntoEachChart) {
  TwoCharts t = MakeTwoCharts(cv::Scalar(100, 60, 200), cv::Scalar(140, 90, 160));
  const SeamBlendSummary summary = BlendSeams(t.face_chart, /*band_rings=*/2, &t.mesh);
  EXPECT_EQ(summary.border_vertices, kN);  // The column i = kSplit.
  EXPECT_NEAR(summary.vertex_difference, (20 + 15 + 20) / 3.0, 1e-3);
  for (int j = 0; j < kN; ++j) {
    // At the border both sides show the mean colour.
    for (const int chart : {0, 1}) {
      const cv::Vec3b border = TexelAt(t.mesh, kSplit, j, chart);
      EXPECT_NEAR(border[0], 120, 1) << j;
      EXPECT_NEAR(border[1], 75, 1) << j;
      EXPECT_NEAR(border[2], 180, 1) << j;
    }
    // One ring in: 2/3 of the pull; three rings in: untouched.
    EXPECT_NEAR(TexelAt(t.mesh, kSplit - 1, j, 0)[0], 100 + 20.0 * 2 / 3, 1) << j;
    EXPECT_NEAR(TexelAt(t.mesh, kSplit + 1, j, 1)[0], 140 - 20.0 * 2 / 3, 1) << j;
    EXPECT_EQ(TexelAt(t.mesh, kSplit - 3, j, 0), cv::Vec3b(100, 60, 200)) << j;
    EXPECT_EQ(TexelAt(t.mesh, kSplit + 3, j, 1), cv::Vec3b(140, 90, 160)) << j;
  }
  // Between vertices the pull is interpolated: halfway between the border and ring 1.
  const Eigen::Vector2f mid = 0.5f * (Uv(kSplit, 2, 0) + Uv(kSplit - 1, 2, 0));
  const cv::Vec3b texel = t.mesh.texture_pages[0].at<cv::Vec3b>(static_cast<int>(mid.y() * 256),
                                                                static_cast<int>(mid.x() * 512));
  EXPECT_NEAR(texel[0], 100 + 0.5 * (20 + 20.0 * 2 / 3), 1.5);
}

TEST(BlendSeams, ZeroRingsTouchOnlyTheBorderFacesAndEqualChartsNothing) {
  TwoCharts t = MakeTwoCharts(cv::Scalar(100, 100, 100), cv::Scalar(140, 140, 140));
  BlendSeams(t.face_chart, /*band_rings=*/0, &t.mesh);
  for (int j = 0; j < kN; ++j) {
    EXPECT_NEAR(TexelAt(t.mesh, kSplit, j, 1)[0], 120, 1);
    EXPECT_EQ(TexelAt(t.mesh, kSplit - 1, j, 0)[0], 100);
    EXPECT_EQ(TexelAt(t.mesh, kSplit + 1, j, 1)[0], 140);
  }

  TwoCharts same = MakeTwoCharts(cv::Scalar(90, 90, 90), cv::Scalar(90, 90, 90));
  const cv::Mat before = same.mesh.texture_pages[0].clone();
  const SeamBlendSummary summary = BlendSeams(same.face_chart, 2, &same.mesh);
  EXPECT_EQ(summary.blended_faces, 0);
  EXPECT_EQ(cv::norm(before, same.mesh.texture_pages[0], cv::NORM_INF), 0.0);
}

TEST(BlendSeams, FacesOutsideChartsAndBadInput) {
  TwoCharts t = MakeTwoCharts(cv::Scalar(100, 100, 100), cv::Scalar(140, 140, 140));
  for (std::size_t f = 0; f < t.face_chart.size(); ++f) {
    if (t.face_chart[f] == 1) t.face_chart[f] = -1;  // Unseen: no border, nothing to blend.
  }
  const SeamBlendSummary summary = BlendSeams(t.face_chart, 2, &t.mesh);
  EXPECT_EQ(summary.border_vertices, 0);
  EXPECT_EQ(summary.blended_faces, 0);
  std::vector<int> short_list(3, 0);
  EXPECT_ANY_THROW(BlendSeams(short_list, 2, &t.mesh));
  EXPECT_ANY_THROW(BlendSeams(t.face_chart, -1, &t.mesh));
}

}  // namespace
}  // namespace reconduit::texture_internal
