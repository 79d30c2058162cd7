#include "core/texture/texture_mesh.h"

#include "core/texture/atlas_packing.h"
#include "core/texture/face_labeling.h"
#include "core/texture/rasterize.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"
#include "core/util/timer.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <boost/pending/disjoint_sets.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

using texture_internal::ProjectChecked;

// Side of the block of unseen_color that faces no view sees point at.
constexpr int kUnseenBlockSize = 4;

// Where a chart's photo rectangle goes in the atlas.
struct ChartPlacement {
  cv::Rect rect;  // In the photo, pixels.
  cv::Size size;  // In the atlas (rect.size() unless shrunk to fit a page).
  int page = 0;
  cv::Point slot;  // Top-left corner on the page.
};

// A point on a border between two charts, and the colour each side's photo shows there.
struct SeamSample {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  int chart[2] = {-1, -1};
  Eigen::Vector3d color[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  bool valid[2] = {false, false};
};

struct AtlasPlan {
  std::vector<ChartPlacement> charts;
  cv::Rect unseen_block;  // On page unseen_page; empty when no face is unseen.
  int unseen_page = -1;
  std::vector<cv::Mat> pages;
};

void CheckInputs(const TriangleMesh& mesh,
                 const std::vector<TextureView>& views,
                 const TextureOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  const int num_vertices = static_cast<int>(mesh.positions.size());
  for (const Eigen::Vector3i& face : mesh.faces) {
    THROW_CHECK(face.minCoeff() >= 0 && face.maxCoeff() < num_vertices)
        << "face " << face.transpose() << " out of range for " << num_vertices << " vertices";
  }
  for (const TextureView& view : views) {
    THROW_CHECK(view.camera.Check(&error)) << "view " << view.name << ": " << error;
    THROW_CHECK(static_cast<bool>(view.load)) << "view " << view.name << " has no loader";
  }
}

// Per face corner (3 f + k), its pixel in the photo of its face's view (faces with a view only).
std::vector<Eigen::Vector2d> CornerPixels(const TriangleMesh& mesh,
                                          const std::vector<TextureView>& views,
                                          const std::vector<int>& labels) {
  std::vector<Eigen::Vector2d> pixels(3 * mesh.faces.size(), Eigen::Vector2d::Zero());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (labels[f] < 0) continue;
    const TextureView& view = views[labels[f]];
    for (int k = 0; k < 3; ++k) {
      const auto pixel = ProjectChecked(
          view.camera, view.cam_from_world * mesh.positions[mesh.faces[f][k]].cast<double>());
      THROW_CHECK(pixel.has_value());  // Candidates project inside their photo.
      pixels[3 * f + k] = *pixel;
    }
  }
  return pixels;
}

AtlasPlan PlanAtlas(const Charts& charts,
                    const std::vector<TextureView>& views,
                    const std::vector<Eigen::Vector2d>& corner_pixels,
                    bool has_unseen,
                    const TextureOptions& options) {
  AtlasPlan plan;
  std::vector<int> widths, heights;
  double total_texels = 0.0;
  for (std::size_t c = 0; c < charts.chart_view.size(); ++c) {
    const Camera& camera = views[charts.chart_view[c]].camera;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
    for (const int f : charts.chart_faces[c]) {
      for (int k = 0; k < 3; ++k) {
        lo = lo.cwiseMin(corner_pixels[3 * f + k]);
        hi = hi.cwiseMax(corner_pixels[3 * f + k]);
      }
    }
    const int x0 = std::max(0, static_cast<int>(std::floor(lo.x())) - options.padding);
    const int y0 = std::max(0, static_cast<int>(std::floor(lo.y())) - options.padding);
    const int x1 =
        std::min(camera.width - 1, static_cast<int>(std::ceil(hi.x())) + options.padding);
    const int y1 =
        std::min(camera.height - 1, static_cast<int>(std::ceil(hi.y())) + options.padding);
    ChartPlacement placement;
    placement.rect = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
    plan.charts.push_back(placement);
    total_texels += double(placement.rect.width) * placement.rect.height;
  }
  // One scale for all charts when their photo rectangles exceed max_megatexels (keeps the
  // relative resolution of the views), and per chart to fit a page.
  const double budget_scale =
      std::min(1.0, std::sqrt(options.max_megatexels * 1e6 / std::max(1.0, total_texels)));
  for (ChartPlacement& placement : plan.charts) {
    const int longest = std::max(placement.rect.width, placement.rect.height);
    const double scale = std::min(budget_scale, options.page_size / static_cast<double>(longest));
    placement.size = placement.rect.size();
    if (scale < 1.0) {
      placement.size.width =
          std::clamp(static_cast<int>(placement.rect.width * scale), 1, options.page_size);
      placement.size.height =
          std::clamp(static_cast<int>(placement.rect.height * scale), 1, options.page_size);
    }
    widths.push_back(placement.size.width);
    heights.push_back(placement.size.height);
  }
  if (has_unseen) {
    widths.push_back(kUnseenBlockSize);
    heights.push_back(kUnseenBlockSize);
  }
  const AtlasLayout layout = PackRectangles(widths, heights, options.page_size);
  for (std::size_t c = 0; c < plan.charts.size(); ++c) {
    plan.charts[c].page = layout.placements[c].page;
    plan.charts[c].slot = cv::Point(layout.placements[c].x, layout.placements[c].y);
  }
  const cv::Scalar unseen(options.unseen_color.x(), options.unseen_color.y(),
                          options.unseen_color.z());
  for (std::size_t p = 0; p < layout.page_widths.size(); ++p) {
    plan.pages.emplace_back(layout.page_heights[p], layout.page_widths[p], CV_8UC3, unseen);
  }
  if (has_unseen) {
    const PackedRect& block = layout.placements.back();
    plan.unseen_page = block.page;
    plan.unseen_block = cv::Rect(block.x, block.y, kUnseenBlockSize, kUnseenBlockSize);
  }
  return plan;
}

// Texture coordinates (glTF: (0, 0) the page's top-left corner, v down) of every corner.
void AssignTexcoords(const Charts& charts,
                     const std::vector<Eigen::Vector2d>& corner_pixels,
                     const AtlasPlan& plan,
                     TriangleMesh* mesh) {
  const std::size_t num_faces = mesh->faces.size();
  mesh->texcoords.assign(3 * num_faces, Eigen::Vector2f::Zero());
  mesh->face_pages.assign(num_faces, 0);
  for (std::size_t f = 0; f < num_faces; ++f) {
    const int c = charts.face_chart[f];
    Eigen::Vector2d atlas[3];
    int page = plan.unseen_page;
    if (c < 0) {
      const Eigen::Vector2d centre(plan.unseen_block.x + 0.5 * (kUnseenBlockSize - 1),
                                   plan.unseen_block.y + 0.5 * (kUnseenBlockSize - 1));
      atlas[0] = atlas[1] = atlas[2] = centre;
    } else {
      const ChartPlacement& chart = plan.charts[c];
      page = chart.page;
      // Pixel centres at integers on both sides; resizing maps centres (i + 0.5) / scale - 0.5.
      const Eigen::Vector2d scale(chart.size.width / double(chart.rect.width),
                                  chart.size.height / double(chart.rect.height));
      const Eigen::Vector2d origin(chart.rect.x, chart.rect.y), slot(chart.slot.x, chart.slot.y);
      for (int k = 0; k < 3; ++k) {
        atlas[k] = (corner_pixels[3 * f + k] - origin + Eigen::Vector2d::Constant(0.5))
                       .cwiseProduct(scale) -
                   Eigen::Vector2d::Constant(0.5) + slot;
      }
    }
    const cv::Mat& image = plan.pages[page];
    for (int k = 0; k < 3; ++k) {
      mesh->texcoords[3 * f + k] =
          Eigen::Vector2f((atlas[k].x() + 0.5) / image.cols, (atlas[k].y() + 0.5) / image.rows);
    }
    mesh->face_pages[f] = page;
  }
}

std::vector<SeamSample> MakeSeamSamples(const TriangleMesh& mesh,
                                        const Charts& charts,
                                        const FaceAdjacency& adjacency) {
  std::vector<SeamSample> samples;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int cf = charts.face_chart[f];
    if (cf < 0) continue;
    for (int n = adjacency.offsets[f]; n < adjacency.offsets[f + 1]; ++n) {
      const int g = adjacency.neighbors[n];
      const int cg = charts.face_chart[g];
      if (g < static_cast<int>(f) || cg < 0 || cg == cf) continue;
      int shared[3], num_shared = 0;
      for (int k = 0; k < 3; ++k) {
        const int vertex = mesh.faces[f][k];
        if ((mesh.faces[g].array() == vertex).any()) shared[num_shared++] = vertex;
      }
      if (num_shared != 2) continue;
      const Eigen::Vector3d a = mesh.positions[shared[0]].cast<double>();
      const Eigen::Vector3d b = mesh.positions[shared[1]].cast<double>();
      for (const Eigen::Vector3d& point : {a, b, Eigen::Vector3d(0.5 * (a + b))}) {
        SeamSample sample;
        sample.point = point;
        sample.chart[0] = cf;
        sample.chart[1] = cg;
        samples.push_back(sample);
      }
    }
  }
  return samples;
}

// Bilinear colour of a CV_8UC3 image at a pixel position (centres at integers), or false.
bool SampleColor(const cv::Mat& image, const Eigen::Vector2d& pixel, Eigen::Vector3d* color) {
  const double x = std::clamp(pixel.x(), 0.0, image.cols - 1.0);
  const double y = std::clamp(pixel.y(), 0.0, image.rows - 1.0);
  if (std::abs(x - pixel.x()) > 0.5 || std::abs(y - pixel.y()) > 0.5) return false;
  const int x0 = std::min(static_cast<int>(x), image.cols - 1),
            x1 = std::min(x0 + 1, image.cols - 1);
  const int y0 = std::min(static_cast<int>(y), image.rows - 1),
            y1 = std::min(y0 + 1, image.rows - 1);
  const double fx = x - x0, fy = y - y0;
  const auto at = [&](int r, int c) {
    const cv::Vec3b& v = image.at<cv::Vec3b>(r, c);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  *color = (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x1)) +
           fy * ((1 - fx) * at(y1, x0) + fx * at(y1, x1));
  return true;
}

// Step 3b: the one pass over the photos. Each view owning charts loads its photo, copies their
// rectangles into their slots (disjoint, so threads write the shared pages safely) and reads
// the colours of the seam samples on its side.
void BakeViews(const std::vector<TextureView>& views,
               const Charts& charts,
               const TextureOptions& options,
               AtlasPlan* plan,
               std::vector<SeamSample>* samples,
               Progress* progress,
               const CancelToken& cancel) {
  std::vector<std::vector<int>> view_charts(views.size());
  for (std::size_t c = 0; c < charts.chart_view.size(); ++c) {
    view_charts[charts.chart_view[c]].push_back(static_cast<int>(c));
  }
  std::vector<std::vector<std::pair<int, int>>> view_samples(views.size());  // (sample, side)
  for (std::size_t i = 0; i < samples->size(); ++i) {
    for (int side = 0; side < 2; ++side) {
      view_samples[charts.chart_view[(*samples)[i].chart[side]]].emplace_back(i, side);
    }
  }
  std::vector<int> used_views;
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (!view_charts[v].empty()) used_views.push_back(static_cast<int>(v));
  }
  if (progress != nullptr) progress->Restart(used_views.size(), "texture: baking photos");
  ParallelFor(
      0, used_views.size(),
      [&](std::size_t i) {
        cancel.ThrowIfCanceled();
        const TextureView& view = views[used_views[i]];
        cv::Mat photo = view.load();
        THROW_CHECK(photo.cols == view.camera.width && photo.rows == view.camera.height)
            << "photo of view " << view.name << " is " << photo.cols << "x" << photo.rows
            << ", its camera " << view.camera.width << "x" << view.camera.height;
        THROW_CHECK(photo.depth() == CV_8U && (photo.channels() == 3 || photo.channels() == 1))
            << "photo of view " << view.name << " is not 8-bit BGR or grey";
        if (photo.channels() == 1) cv::cvtColor(photo, photo, cv::COLOR_GRAY2BGR);
        for (const int c : view_charts[used_views[i]]) {
          const ChartPlacement& chart = plan->charts[c];
          cv::Mat target = plan->pages[chart.page](cv::Rect(chart.slot, chart.size));
          if (chart.size == chart.rect.size()) {
            photo(chart.rect).copyTo(target);
          } else {
            cv::Mat shrunk;
            cv::resize(photo(chart.rect), shrunk, chart.size, 0, 0, cv::INTER_AREA);
            shrunk.copyTo(target);
          }
        }
        for (const auto& [index, side] : view_samples[used_views[i]]) {
          SeamSample& sample = (*samples)[index];
          const auto pixel = ProjectChecked(view.camera, view.cam_from_world * sample.point);
          sample.valid[side] = pixel && SampleColor(photo, *pixel, &sample.color[side]);
        }
        if (progress != nullptr) progress->Advance();
      },
      options.num_threads);
}

// Offsets of one channel minimising sum_i w_i (o_a - o_b - d_i)² + kRidge sum_c o_c².
Eigen::VectorXd SolveOffsets(const std::vector<const SeamSample*>& used,
                             const std::vector<double>& weights,
                             int channel,
                             int num_charts) {
  constexpr double kRidge = 0.1;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(num_charts);
  for (std::size_t i = 0; i < used.size(); ++i) {
    const int a = used[i]->chart[0], b = used[i]->chart[1];
    const double w = weights[i];
    const double d = used[i]->color[1][channel] - used[i]->color[0][channel];
    triplets.emplace_back(a, a, w);
    triplets.emplace_back(b, b, w);
    triplets.emplace_back(a, b, -w);
    triplets.emplace_back(b, a, -w);
    rhs[a] += w * d;
    rhs[b] -= w * d;
  }
  for (int c = 0; c < num_charts; ++c) triplets.emplace_back(c, c, kRidge);
  Eigen::SparseMatrix<double> normal(num_charts, num_charts);
  normal.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  THROW_CHECK(solver.info() == Eigen::Success) << "seam levelling: factorisation failed";
  return solver.solve(rhs);
}

// Per chart, the area of its faces in its photo, pixels.
std::vector<double> ChartAreas(const Charts& charts,
                               const std::vector<Eigen::Vector2d>& corner_pixels) {
  std::vector<double> areas(charts.chart_faces.size(), 0.0);
  for (std::size_t c = 0; c < areas.size(); ++c) {
    for (const int f : charts.chart_faces[c]) {
      const Eigen::Vector2d e1 = corner_pixels[3 * f + 1] - corner_pixels[3 * f];
      const Eigen::Vector2d e2 = corner_pixels[3 * f + 2] - corner_pixels[3 * f];
      areas[c] += 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    }
  }
  return areas;
}

// The free constant of each group of charts that seams connect: the least-squares fit fixes
// only differences, and the ridge alone would fix the constant at a zero mean over CHARTS, so
// that many small charts (seen at their borders from other photos) shift the big ones: on
// fountain-P11 the levelled texture came out 5 grey levels brighter than its photos on
// average, and the model rendered through the first photo's camera differed from it by 10.4
// grey levels (6.9 unlevelled). Shifting each group so that its texel-weighted mean offset is
// zero keeps the texture's average colour the photos' own (8.7 there; the mean over the eleven
// photos 5.85, unlevelled 5.73, with seams levelled from 11.6 to 3.8).
void CenterOffsetsByArea(const std::vector<const SeamSample*>& used,
                         const std::vector<double>& chart_areas,
                         Eigen::MatrixXd* offsets) {
  const int num_charts = static_cast<int>(offsets->rows());
  std::vector<int> rank(num_charts), parent(num_charts);
  boost::disjoint_sets<int*, int*> groups(rank.data(), parent.data());
  for (int c = 0; c < num_charts; ++c) groups.make_set(c);
  for (const SeamSample* sample : used) groups.union_set(sample->chart[0], sample->chart[1]);
  std::vector<double> area(num_charts, 0.0);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(num_charts, 3);
  for (int c = 0; c < num_charts; ++c) {
    const int group = groups.find_set(c);
    area[group] += chart_areas[c];
    sum.row(group) += chart_areas[c] * offsets->row(c);
  }
  for (int c = 0; c < num_charts; ++c) {
    const int group = groups.find_set(c);
    if (area[group] > 0.0) offsets->row(c) -= sum.row(group) / area[group];
  }
}

// Step 4: seam levelling. Unknowns: an additive offset o_c per chart and channel. Each seam
// sample between charts a and b asks o_a - o_b = colour_b - colour_a; a small ridge term
// (0.1 o_c², against a weight of about 1 per sample) makes the normal equations (a graph
// Laplacian plus a ridge) symmetric positive definite, solved by sparse Cholesky, and leaves
// isolated charts unchanged; each connected group's free constant is then set so that its
// texel-weighted mean offset is zero (CenterOffsetsByArea). Samples on textured borders differ by
// resampling and registration noise with heavy tails (a shape edge seen half a pixel apart), so the
// fit is robust: Huber weights (kHuber grey levels) by iteratively reweighted least squares, 4
// rounds. Why per chart and additive: the differences between photos of a surface are mostly
// exposure and white balance, constant over a photo; a gain would model exposure better on dark-to-
// bright ranges, but at the levels of 8-bit photos an offset fits seams to within noise, keeps
// the problem linear with one solution, and cannot flip contrast. Waechter's per-vertex
// adjustment also removes gradual changes within a chart, at the price of a system of the
// size of the mesh's border vertices plus a Poisson step; per chart is the simpler start.
void LevelSeams(const std::vector<SeamSample>& samples,
                const std::vector<double>& chart_areas,
                const TextureOptions& options,
                AtlasPlan* plan,
                TextureSummary* summary) {
  constexpr double kHuber = 4.0;
  constexpr int kRounds = 4;
  const int num_charts = static_cast<int>(plan->charts.size());
  std::vector<const SeamSample*> used;
  for (const SeamSample& sample : samples) {
    if (!sample.valid[0] || !sample.valid[1]) continue;
    const Eigen::Vector3d difference = sample.color[1] - sample.color[0];
    if (difference.cwiseAbs().maxCoeff() > options.seam_outlier_threshold) continue;
    used.push_back(&sample);
  }
  summary->num_seam_samples = static_cast<int>(used.size());
  if (used.empty()) return;
  Eigen::MatrixXd offsets(num_charts, 3);
  for (int channel = 0; channel < 3; ++channel) {
    std::vector<double> weights(used.size(), 1.0);
    for (int round = 0; round < kRounds; ++round) {
      offsets.col(channel) = SolveOffsets(used, weights, channel, num_charts);
      for (std::size_t i = 0; i < used.size(); ++i) {
        const double residual =
            std::abs(used[i]->color[1][channel] + offsets(used[i]->chart[1], channel) -
                     used[i]->color[0][channel] - offsets(used[i]->chart[0], channel));
        weights[i] = residual <= kHuber ? 1.0 : kHuber / residual;
      }
    }
  }
  CenterOffsetsByArea(used, chart_areas, &offsets);

  double before = 0.0, after = 0.0;
  for (const SeamSample* sample : used) {
    const Eigen::Vector3d a = sample->color[0] + offsets.row(sample->chart[0]).transpose();
    const Eigen::Vector3d b = sample->color[1] + offsets.row(sample->chart[1]).transpose();
    before += (sample->color[1] - sample->color[0]).cwiseAbs().sum();
    after += (b - a).cwiseAbs().sum();
  }
  summary->seam_difference_before = before / (3.0 * used.size());
  summary->seam_difference_after = after / (3.0 * used.size());
  for (int c = 0; c < num_charts; ++c) {
    const ChartPlacement& chart = plan->charts[c];
    cv::Mat target = plan->pages[chart.page](cv::Rect(chart.slot, chart.size));
    cv::add(target, cv::Scalar(offsets(c, 0), offsets(c, 1), offsets(c, 2)), target);
  }
}

}  // namespace

bool TextureOptions::Check(std::string* error) const {
  std::ostringstream message;
  if (page_size < 64) {
    message << "page_size must be >= 64, got " << page_size;
  } else if (padding < 0 || padding > 16) {
    message << "padding must be in [0, 16], got " << padding;
  } else if (visibility_max_side < 64) {
    message << "visibility_max_side must be >= 64, got " << visibility_max_side;
  } else if (!(depth_tolerance > 0.0 && depth_tolerance < 1.0)) {
    message << "depth_tolerance must be in (0, 1), got " << depth_tolerance;
  } else if (!(max_view_angle_deg > 0.0 && max_view_angle_deg < 90.0)) {
    message << "max_view_angle_deg must be in (0, 90), got " << max_view_angle_deg;
  } else if (!(smoothness_weight >= 0.0) || !std::isfinite(smoothness_weight)) {
    message << "smoothness_weight must be >= 0 and finite, got " << smoothness_weight;
  } else if (max_smoothing_sweeps < 0) {
    message << "max_smoothing_sweeps must be >= 0, got " << max_smoothing_sweeps;
  } else if (!(max_megatexels > 0.0)) {
    message << "max_megatexels must be > 0, got " << max_megatexels;
  } else if (!(seam_outlier_threshold > 0.0)) {
    message << "seam_outlier_threshold must be > 0, got " << seam_outlier_threshold;
  } else if (!(unseen_color.minCoeff() >= 0.0 && unseen_color.maxCoeff() <= 255.0)) {
    message << "unseen_color must be in [0, 255] per channel";
  } else {
    return true;
  }
  if (error != nullptr) *error = message.str();
  return false;
}

TextureResult TextureMesh(const TriangleMesh& mesh,
                          const std::vector<TextureView>& views,
                          const TextureOptions& options,
                          Progress* progress,
                          const CancelToken& cancel) {
  CheckInputs(mesh, views, options);
  const Timer total;
  TextureResult result;
  TextureSummary& summary = result.summary;
  summary.num_faces = static_cast<int>(mesh.faces.size());
  result.mesh = mesh;
  result.mesh.texcoords.clear();
  result.mesh.face_pages.clear();
  result.mesh.texture_pages.clear();
  if (mesh.faces.empty()) return result;

  Timer step;
  if (progress != nullptr) progress->Restart(views.size(), "texture: visibility");
  const FaceCandidates candidates = ComputeFaceCandidates(mesh, views, options, progress, cancel);
  summary.visibility_seconds = step.ElapsedSeconds();
  cancel.ThrowIfCanceled();

  step.Restart();
  const FaceAdjacency adjacency = ComputeFaceAdjacency(mesh);
  result.face_views = SelectBestViews(candidates);
  summary.num_charts_greedy =
      static_cast<int>(ComputeCharts(result.face_views, adjacency).chart_view.size());
  summary.smoothing_sweeps = SmoothLabels(candidates, adjacency, options.smoothness_weight,
                                          options.max_smoothing_sweeps, &result.face_views);
  const Charts charts = ComputeCharts(result.face_views, adjacency);
  summary.num_charts = static_cast<int>(charts.chart_view.size());
  summary.num_unseen_faces =
      static_cast<int>(std::count(result.face_views.begin(), result.face_views.end(), -1));
  summary.num_textured_faces = summary.num_faces - summary.num_unseen_faces;
  summary.labelling_seconds = step.ElapsedSeconds();
  cancel.ThrowIfCanceled();

  step.Restart();
  const std::vector<Eigen::Vector2d> corner_pixels = CornerPixels(mesh, views, result.face_views);
  AtlasPlan plan = PlanAtlas(charts, views, corner_pixels, summary.num_unseen_faces > 0, options);
  AssignTexcoords(charts, corner_pixels, plan, &result.mesh);
  std::vector<SeamSample> samples;
  if (options.level_seams) samples = MakeSeamSamples(mesh, charts, adjacency);
  summary.atlas_seconds = step.ElapsedSeconds();

  step.Restart();
  BakeViews(views, charts, options, &plan, &samples, progress, cancel);
  summary.bake_seconds = step.ElapsedSeconds();
  cancel.ThrowIfCanceled();

  step.Restart();
  if (options.level_seams) {
    LevelSeams(samples, ChartAreas(charts, corner_pixels), options, &plan, &summary);
  }
  summary.levelling_seconds = step.ElapsedSeconds();

  summary.num_pages = static_cast<int>(plan.pages.size());
  result.mesh.texture_pages = std::move(plan.pages);
  summary.total_seconds = total.ElapsedSeconds();
  if (progress != nullptr) progress->Finish();
  LOG_INFO << "texture: " << summary.num_faces << " faces, " << summary.num_textured_faces
           << " textured, " << summary.num_unseen_faces << " unseen; charts "
           << summary.num_charts_greedy << " greedy -> " << summary.num_charts << " after "
           << summary.smoothing_sweeps << " sweeps; " << summary.num_pages << " pages; seams "
           << summary.seam_difference_before << " -> " << summary.seam_difference_after << " over "
           << summary.num_seam_samples << " samples; " << summary.visibility_seconds
           << " s visibility, " << summary.labelling_seconds << " s labelling, "
           << summary.atlas_seconds << " s atlas, " << summary.bake_seconds << " s baking, "
           << summary.levelling_seconds << " s levelling";
  return result;
}

}  // namespace reconduit
