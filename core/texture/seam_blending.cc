#include "core/texture/seam_blending.h"

#include "core/texture/rasterize.h"
#include "core/util/logging.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace reconduit::texture_internal {
namespace {

// A vertex as part of one chart (a border vertex has one per chart that meets there).
std::uint64_t Key(int vertex, int chart) {
  return (static_cast<std::uint64_t>(vertex) << 32) | static_cast<std::uint32_t>(chart);
}

struct VertexOffset {
  Eigen::Vector3f offset = Eigen::Vector3f::Zero();
  int ring = 0;
};

// The atlas pixel (centres at integers) of a face corner's texture coordinate.
Eigen::Vector2d AtlasPixel(const TriangleMesh& mesh, std::size_t face, int corner) {
  const cv::Mat& page = mesh.texture_pages[mesh.face_pages[face]];
  const Eigen::Vector2f& uv = mesh.texcoords[3 * face + corner];
  return {uv.x() * page.cols - 0.5, uv.y() * page.rows - 0.5};
}

Eigen::Vector3f Bilinear(const cv::Mat& page, const Eigen::Vector2d& pixel) {
  const double x = std::clamp(pixel.x(), 0.0, page.cols - 1.0);
  const double y = std::clamp(pixel.y(), 0.0, page.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, page.cols - 1), y1 = std::min(y0 + 1, page.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const auto at = [&](int yy, int xx) {
    const cv::Vec3b& c = page.at<cv::Vec3b>(yy, xx);
    return Eigen::Vector3f(c[0], c[1], c[2]);
  };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x1)) +
         fy * ((1 - fx) * at(y1, x0) + fx * at(y1, x1));
}

// Ring 0: the offsets at the border vertices, per chart.
std::unordered_map<std::uint64_t, VertexOffset> BorderOffsets(const std::vector<int>& face_chart,
                                                              const TriangleMesh& mesh,
                                                              SeamBlendSummary* summary) {
  // Per vertex, the texel of each chart that has it (the first corner found: all corners of a
  // vertex within a chart share its texture coordinate).
  std::unordered_map<std::uint64_t, Eigen::Vector3f> texel;
  std::vector<int> first_chart(mesh.positions.size(), -1);
  std::vector<char> border(mesh.positions.size(), 0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int chart = face_chart[f];
    if (chart < 0) continue;
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces[f][k];
      const auto [slot, added] = texel.try_emplace(Key(v, chart));
      if (!added) continue;
      slot->second = Bilinear(mesh.texture_pages[mesh.face_pages[f]], AtlasPixel(mesh, f, k));
      if (first_chart[v] < 0) first_chart[v] = chart;
      if (first_chart[v] != chart) border[v] = 1;
    }
  }
  // Means over each border vertex's charts.
  std::vector<Eigen::Vector3f> sum(mesh.positions.size(), Eigen::Vector3f::Zero());
  std::vector<int> count(mesh.positions.size(), 0);
  for (const auto& [key, color] : texel) {
    const int v = static_cast<int>(key >> 32);
    if (!border[v]) continue;
    sum[v] += color;
    ++count[v];
  }
  std::unordered_map<std::uint64_t, VertexOffset> offsets;
  double difference = 0.0;
  for (const auto& [key, color] : texel) {
    const int v = static_cast<int>(key >> 32);
    if (!border[v]) continue;
    const Eigen::Vector3f offset = sum[v] / static_cast<float>(count[v]) - color;
    offsets[key] = {offset, 0};
    difference += offset.cwiseAbs().sum() / 3.0;
  }
  summary->border_vertices = static_cast<int>(std::count(border.begin(), border.end(), 1));
  summary->vertex_difference = offsets.empty() ? 0.0 : difference / offsets.size();
  return offsets;
}

// Rings 1..band_rings: each vertex of a chart not reached yet takes the mean offset of its
// neighbours (within the chart's faces) of the previous ring.
void SpreadIntoCharts(const std::vector<int>& face_chart,
                      const TriangleMesh& mesh,
                      int band_rings,
                      std::unordered_map<std::uint64_t, VertexOffset>* offsets) {
  for (int ring = 1; ring <= band_rings; ++ring) {
    std::unordered_map<std::uint64_t, std::pair<Eigen::Vector3f, int>> next;
    for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
      const int chart = face_chart[f];
      if (chart < 0) continue;
      for (int k = 0; k < 3; ++k) {
        const auto from = offsets->find(Key(mesh.faces[f][k], chart));
        if (from == offsets->end() || from->second.ring != ring - 1) continue;
        for (int j = 1; j < 3; ++j) {
          const std::uint64_t to = Key(mesh.faces[f][(k + j) % 3], chart);
          if (offsets->count(to)) continue;
          auto& [total, n] = next.try_emplace(to, Eigen::Vector3f::Zero(), 0).first->second;
          total += from->second.offset;
          ++n;
        }
      }
    }
    for (const auto& [key, value] : next) {
      (*offsets)[key] = {value.first / static_cast<float>(value.second), ring};
    }
  }
  for (auto& [key, value] : *offsets) {
    value.offset *= 1.0f - static_cast<float>(value.ring) / static_cast<float>(band_rings + 1);
  }
}

}  // namespace

SeamBlendSummary BlendSeams(const std::vector<int>& face_chart,
                            int band_rings,
                            TriangleMesh* mesh) {
  THROW_CHECK_EQ(face_chart.size(), mesh->faces.size());
  THROW_CHECK_GE(band_rings, 0);
  SeamBlendSummary summary;
  if (mesh->texture_pages.empty()) return summary;
  std::unordered_map<std::uint64_t, VertexOffset> offsets =
      BorderOffsets(face_chart, *mesh, &summary);
  if (offsets.empty()) return summary;
  SpreadIntoCharts(face_chart, *mesh, band_rings, &offsets);

  for (std::size_t page_index = 0; page_index < mesh->texture_pages.size(); ++page_index) {
    cv::Mat& page = mesh->texture_pages[page_index];
    cv::Mat done(page.size(), CV_8UC1, cv::Scalar(0));
    for (std::size_t f = 0; f < mesh->faces.size(); ++f) {
      const int chart = face_chart[f];
      if (chart < 0 || mesh->face_pages[f] != static_cast<int>(page_index)) continue;
      Eigen::Vector3f corner_offset[3];
      bool any = false;
      for (int k = 0; k < 3; ++k) {
        const auto found = offsets.find(Key(mesh->faces[f][k], chart));
        corner_offset[k] = found == offsets.end() ? Eigen::Vector3f::Zero() : found->second.offset;
        any = any || corner_offset[k].cwiseAbs().maxCoeff() >= 0.5f;
      }
      if (!any) continue;
      ++summary.blended_faces;
      RasterizeTriangle(AtlasPixel(*mesh, f, 0), AtlasPixel(*mesh, f, 1), AtlasPixel(*mesh, f, 2),
                        page.cols, page.rows, [&](int x, int y, double b0, double b1, double b2) {
                          std::uint8_t& visited = done.at<std::uint8_t>(y, x);
                          if (visited) return;
                          visited = 1;
                          const Eigen::Vector3f offset = static_cast<float>(b0) * corner_offset[0] +
                                                         static_cast<float>(b1) * corner_offset[1] +
                                                         static_cast<float>(b2) * corner_offset[2];
                          cv::Vec3b& texel = page.at<cv::Vec3b>(y, x);
                          for (int c = 0; c < 3; ++c)
                            texel[c] = cv::saturate_cast<std::uint8_t>(texel[c] + offset[c]);
                        });
    }
  }
  return summary;
}

}  // namespace reconduit::texture_internal
