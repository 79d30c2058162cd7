// Speed and memory of TextureMesh at the scale of fountain-P11 (not a test: run by hand).
//
//   build/ci/core/texture/texture_benchmark [cells_per_side=500] [views=11]
//
// A wall of cells_per_side² x 2 faces (500: 500 k faces), its vertices jittered along the normal
// by 1 % of a cell so that views compete face by face, seen by `views` cameras of 3072 x 2048
// px (fountain-P11's size and focal length) on an arc 6 m away. Photos are random noise made by
// the loader on each call (as decoding would), so the figures are the texturing's own.
#include "core/texture/texture_mesh.h"
#include "core/texture/texture_test_util.h"
#include "core/util/timer.h"

#include <cstdio>
#include <cstdlib>
#include <random>

int main(int argc, char** argv) {
  using namespace reconduit;
  const int cells = argc > 1 ? std::atoi(argv[1]) : 500;
  const int num_views = argc > 2 ? std::atoi(argv[2]) : 11;
  TriangleMesh mesh;
  texture_test::AppendQuad(
      texture_test::MakeQuad({-3, 2, -1}, {6, 0, 0}, {0, 0, 4}, 1, {128, 128, 128}), cells, cells,
      false, &mesh);
  std::mt19937 rng(1);
  std::normal_distribution<float> jitter(0.0f, 0.01f * 6.0f / cells);
  for (Eigen::Vector3f& p : mesh.positions) p.y() += jitter(rng);
  Camera camera = Camera::FromFocal(3072, 2048, 2760.0);
  camera.k1 = -0.05;
  std::vector<TextureView> views;
  for (int v = 0; v < num_views; ++v) {
    const double angle = (v - (num_views - 1) / 2.0) * 0.08;
    TextureView view;
    view.name = std::to_string(v);
    view.camera = camera;
    view.cam_from_world = Rigid3d::LookAt({6 * std::sin(angle), 2 - 6 * std::cos(angle), 1.0},
                                          {0, 2, 1}, Eigen::Vector3d::UnitZ());
    view.load = [camera, v] {
      cv::Mat photo(camera.height, camera.width, CV_8UC3);
      cv::randu(photo, cv::Scalar::all(v), cv::Scalar::all(200 + v));
      return photo;
    };
    views.push_back(view);
  }
  const std::int64_t before = CurrentMemoryBytes();
  const TextureResult result = TextureMesh(mesh, views, TextureOptions(), nullptr, CancelToken());
  const TextureSummary& s = result.summary;
  long texels = 0;
  for (const cv::Mat& page : result.mesh.texture_pages) texels += long(page.cols) * page.rows;
  std::printf(
      "%d faces, %d views: %d textured, %d unseen; charts %d greedy -> %d (%d sweeps); %d pages, "
      "%.1f Mtexels\n"
      "seconds: visibility %.2f, labelling %.2f, atlas %.2f, baking %.2f, levelling %.2f, "
      "total %.2f\n"
      "memory: %.0f MB before, peak %.0f MB\n",
      s.num_faces, num_views, s.num_textured_faces, s.num_unseen_faces, s.num_charts_greedy,
      s.num_charts, s.smoothing_sweeps, s.num_pages, texels / 1e6, s.visibility_seconds,
      s.labelling_seconds, s.atlas_seconds, s.bake_seconds, s.levelling_seconds, s.total_seconds,
      before / 1e6, PeakMemoryBytes() / 1e6);
  return 0;
}
