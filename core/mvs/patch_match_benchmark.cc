// PatchMatch speed and accuracy on a rendered scene with exact depth (issue 10's budget: about
// 10 s wall per 1536 x 1024 depth map with ~6 sources on 2 cores).
//
// Scene: a textured floor (z = 0) with a textured box (1.2 x 1.0 x 0.8 m) on it, seen 45 deg
// from above at ~5.7 m, so the floor is slanted in every view and the box's edges are depth
// discontinuities. The reference looks at the origin; the sources sit 0.5-1.3 m beside and
// above it, looking at the same point (triangulation angles 5-13 deg). Renders use 2 x 2 rays
// per pixel and a 0.7 px blur (as patch_match_test, which uses 4 x 4: rendering 7 full-size
// views at 4 x 4 takes longer than matching them).
//
// Prints wall and CPU time of ComputeDepthMap alone, completeness (share of true-surface
// pixels at least a window from the border that get a depth), accuracy (share of the filled
// depths within 0.1 % and 0.2 % of the true depth) and the median relative error. --noise adds
// Gaussian noise of that many grey levels to every photo.
//
// Usage: mvs_patch_match_benchmark [--width W] [--height H] [--sources N] [--threads T]
//                                  [--iterations I] [--levels L] [--up_iterations U]
//                                  [--up_first F] [--simd 0|1] [--noise SIGMA] [--repeat R]
#include "core/mvs/patch_match.h"
#include "core/scene/render.h"
#include "core/scene/textured_scene.h"
#include "core/util/timer.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/resource.h>
#include <vector>

namespace reconduit {
namespace {

struct BenchmarkArgs {
  int width = 1536;
  int height = 1024;
  int num_sources = 6;
  int repeat = 1;
  int noise = 0;  // Standard deviation of Gaussian noise added to every photo, grey levels.
  PatchMatchOptions options;
};

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

TexturedQuad Quad(const Eigen::Vector3d& origin,
                  const Eigen::Vector3d& u,
                  const Eigen::Vector3d& v,
                  std::uint64_t seed) {
  TexturedQuad quad;
  quad.origin = origin;
  quad.edge_u = u;
  quad.edge_v = v;
  quad.texture.seed = seed;
  quad.texture.cell_size = 0.2;
  return quad;
}

TexturedScene FloorAndBox() {
  TexturedScene scene;
  scene.quads.push_back(Quad({-8, -8, 0}, {16, 0, 0}, {0, 16, 0}, 1));
  const double x0 = -0.6, x1 = 0.6, y0 = -0.5, y1 = 0.5, h = 0.8;
  scene.quads.push_back(Quad({x0, y0, h}, {x1 - x0, 0, 0}, {0, y1 - y0, 0}, 2));  // Top.
  scene.quads.push_back(Quad({x0, y0, 0}, {x1 - x0, 0, 0}, {0, 0, h}, 3));        // Front.
  scene.quads.push_back(Quad({x0, y1, 0}, {x1 - x0, 0, 0}, {0, 0, h}, 4));        // Back.
  scene.quads.push_back(Quad({x0, y0, 0}, {0, y1 - y0, 0}, {0, 0, h}, 5));        // Left.
  scene.quads.push_back(Quad({x1, y0, 0}, {0, y1 - y0, 0}, {0, 0, h}, 6));        // Right.
  return scene;
}

struct View {
  MvsView view;
  cv::Mat true_depth;
};

View Render(const TexturedScene& scene,
            const Eigen::Vector3d& center,
            const BenchmarkArgs& args,
            std::uint64_t seed) {
  const int width = args.width, height = args.height;
  View v;
  // Focal 0.85 x the width: fountain-P11's at half resolution (1536 px wide) is about 1380 px.
  v.view.camera = Camera::FromFocal(width, height, 0.85 * width);
  v.view.cam_from_world =
      Rigid3d::LookAt(center, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
  RenderOptions options;
  options.grayscale = true;
  options.samples_per_axis = 2;
  const RenderedView rendered = RenderScene(scene, v.view.camera, v.view.cam_from_world, options);
  rendered.image.convertTo(v.view.gray, CV_32FC1);
  cv::GaussianBlur(v.view.gray, v.view.gray, cv::Size(0, 0), 0.7);
  if (args.noise > 0) {
    cv::Mat noise(v.view.gray.size(), CV_32FC1);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, static_cast<double>(args.noise));
    v.view.gray += noise;
  }
  v.true_depth = rendered.depth;
  return v;
}

// Reference at (0, -4, 4); sources offset along the reference's right (x) and up directions.
std::vector<View> RenderViews(const BenchmarkArgs& args) {
  const TexturedScene scene = FloorAndBox();
  const Eigen::Vector3d reference(0, -4, 4);
  const Eigen::Vector3d up = Eigen::Vector3d(0, 1, 1).normalized();
  const std::vector<Eigen::Vector2d> offsets = {{0.7, 0},   {-0.7, 0},    {0, 0.6},   {0, -0.6},
                                                {1.3, 0.3}, {-1.2, -0.4}, {0.5, 0.5}, {-0.5, 0.5}};
  std::vector<View> views = {Render(scene, reference, args, 1)};
  for (int s = 0; s < args.num_sources; ++s) {
    const Eigen::Vector2d& o = offsets[s % offsets.size()];
    const double scale = 1.0 + static_cast<double>(s / offsets.size()) * 0.5;
    const Eigen::Vector3d center =
        reference + scale * (o.x() * Eigen::Vector3d::UnitX() + o.y() * up);
    views.push_back(Render(scene, center, args, static_cast<std::uint64_t>(s) + 2));
  }
  return views;
}

void Evaluate(const DepthMap& map, const cv::Mat& truth, int margin) {
  long total = 0, filled = 0, within_1 = 0, within_2 = 0;
  std::vector<float> errors;
  for (int y = margin; y < truth.rows - margin; ++y) {
    for (int x = margin; x < truth.cols - margin; ++x) {
      const float t = truth.at<float>(y, x);
      if (t <= 0.0f) continue;
      ++total;
      const float d = map.depth.at<float>(y, x);
      if (d <= 0.0f) continue;
      ++filled;
      const float error = std::abs(d - t) / t;
      errors.push_back(error);
      within_1 += error <= 0.001f;
      within_2 += error <= 0.002f;
    }
  }
  double median = 0.0;
  if (!errors.empty()) {
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    median = errors[errors.size() / 2];
  }
  const double f = std::max<long>(filled, 1);
  std::printf("completeness %.4f  within 0.1%% %.4f  within 0.2%% %.4f  median error %.5f %%\n",
              static_cast<double>(filled) / std::max<long>(total, 1), within_1 / f, within_2 / f,
              100.0 * median);
}

int ParseInt(const char* text) {
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (end == text || *end != '\0') {
    std::fprintf(stderr, "not an integer: %s\n", text);
    std::exit(2);
  }
  return static_cast<int>(value);
}

BenchmarkArgs ParseArgs(int argc, char** argv) {
  BenchmarkArgs args;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "missing value after %s\n", flag.c_str());
      std::exit(2);
    }
    const int value = ParseInt(argv[++i]);
    if (flag == "--width")
      args.width = value;
    else if (flag == "--height")
      args.height = value;
    else if (flag == "--sources")
      args.num_sources = value;
    else if (flag == "--threads")
      args.options.num_threads = value;
    else if (flag == "--iterations")
      args.options.num_iterations = value;
    else if (flag == "--levels")
      args.options.pyramid_levels = value;
    else if (flag == "--up_iterations")
      args.options.upsampled_iterations = value;
    else if (flag == "--up_first")
      args.options.upsampled_first_iteration = value;
    else if (flag == "--simd")
      args.options.use_simd = value != 0;
    else if (flag == "--noise")
      args.noise = value;
    else if (flag == "--repeat")
      args.repeat = value;
    else {
      std::fprintf(stderr, "unknown flag %s\n", flag.c_str());
      std::exit(2);
    }
  }
  return args;
}

int Main(int argc, char** argv) {
  const BenchmarkArgs args = ParseArgs(argc, argv);
  std::string error;
  if (!args.options.Check(&error)) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 2;
  }
  const Timer render_timer;
  const std::vector<View> views = RenderViews(args);
  std::printf("rendered %d x %d, 1 + %d views in %.1f s\n", args.width, args.height,
              args.num_sources, render_timer.ElapsedSeconds());
  PatchMatchInput input;
  input.reference = &views[0].view;
  for (std::size_t s = 1; s < views.size(); ++s) input.sources.push_back(&views[s].view);
  input.min_depth = 2.0;
  input.max_depth = 20.0;
  for (int r = 0; r < args.repeat; ++r) {
    const Timer timer;
    const double cpu = CpuSeconds();
    const DepthMap map = ComputeDepthMap(input, args.options);
    const PatchMatchOptions& o = args.options;
    std::printf("iterations %d, levels %d (then %d from %d), threads %d: wall %.2f s, cpu %.2f s\n",
                o.num_iterations, o.pyramid_levels, o.upsampled_iterations,
                o.upsampled_first_iteration, o.num_threads, timer.ElapsedSeconds(),
                CpuSeconds() - cpu);
    Evaluate(map, views[0].true_depth, args.options.window_radius);
  }
  return 0;
}

}  // namespace
}  // namespace reconduit

int main(int argc, char** argv) { return reconduit::Main(argc, argv); }
