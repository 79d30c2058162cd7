// Writes the browser test's inputs (tests/gltf/gltf.test.mjs) into the folder given:
//   model.glb      the textured cube of core/io/gltf_test_util.h (two atlas pages) seen by
//                  4 photos from above, in a world whose up is +Z (so y-up really rotates);
//   labels.bin     for photo 0000.jpg (1024 x 768, distortion-free, centred principal point),
//                  which side of the cube each pixel sees by our camera model (ray casting):
//                  one byte per pixel, row-major from the top, 0 = background, s + 1 = side s;
//   expected.json  the photo's name and size, the side colours (RGB) and the labels' name.
// Usage: write_test_glb OUT_DIR
#include "core/io/gltf.h"
#include "core/io/gltf_test_util.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace {

using namespace reconduit;

const Eigen::Vector3d kCenter(1.0, 2.0, 3.0);
constexpr double kHalf = 0.5;

// The side of the cube a ray from `origin` along `dir` enters first, or -1.
int SideHit(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) {
  double t_enter = -std::numeric_limits<double>::infinity();
  double t_exit = std::numeric_limits<double>::infinity();
  int side = -1;
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = kCenter[axis] - kHalf, hi = kCenter[axis] + kHalf;
    if (std::abs(dir[axis]) < 1e-15) {
      if (origin[axis] < lo || origin[axis] > hi) return -1;
      continue;
    }
    double t0 = (lo - origin[axis]) / dir[axis], t1 = (hi - origin[axis]) / dir[axis];
    // Entering through the low face (dir > 0) is side 2 axis + 1 (-x, -y, -z), else 2 axis.
    int enter_side = dir[axis] > 0 ? 2 * axis + 1 : 2 * axis;
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > t_enter) {
      t_enter = t0;
      side = enter_side;
    }
    t_exit = std::min(t_exit, t1);
  }
  return t_enter <= t_exit && t_enter > 0 ? side : -1;
}

std::vector<GltfCameraView> Cameras() {
  const Camera camera = Camera::FromFocal(1024, 768, 900.0);
  std::vector<GltfCameraView> views;
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  for (int i = 0; i < 4; ++i) {
    const double angle = 0.4 + 0.5 * i;  // A quarter ring, from above.
    const Eigen::Vector3d center =
        kCenter + 2.6 * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0) + 1.4 * up;
    // Aimed a little off the cube's centre, so the cube is not in the middle of the image.
    const Eigen::Vector3d target = kCenter + Eigen::Vector3d(0.1, -0.15, 0.05);
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.jpg", i);
    views.push_back({name, camera, Rigid3d::LookAt(center, target, up)});
  }
  return views;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: write_test_glb OUT_DIR\n");
    return 2;
  }
  const std::filesystem::path out = argv[1];
  std::filesystem::create_directories(out);
  const TriangleMesh mesh = testing_util::MakeCube(kCenter.cast<float>(), float(kHalf), 2);
  const std::vector<GltfCameraView> cameras = Cameras();
  GltfSummary summary;
  const Status status = WriteModelGlb(out / "model.glb", mesh, cameras, GltfOptions(), &summary);
  if (!status.ok()) {
    std::fprintf(stderr, "write_test_glb: %s\n", status.ToString().c_str());
    return 1;
  }
  const GltfCameraView& view = cameras[0];
  const Camera& c = view.camera;
  const Eigen::Matrix3d world_from_cam =
      view.cam_from_world.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d origin = view.cam_from_world.CenterInWorld();
  std::vector<unsigned char> labels(static_cast<std::size_t>(c.width) * c.height, 0);
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      const Eigen::Vector2d n = c.NormalizedFromPixel(Eigen::Vector2d(x, y));
      const int side = SideHit(origin, world_from_cam * Eigen::Vector3d(n.x(), n.y(), 1.0));
      labels[static_cast<std::size_t>(y) * c.width + x] = static_cast<unsigned char>(side + 1);
    }
  }
  std::ofstream(out / "labels.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(labels.data()),
             static_cast<std::streamsize>(labels.size()));
  nlohmann::json colors = nlohmann::json::array();
  for (int s = 0; s < 6; ++s) {
    const auto rgb = testing_util::SideColor(s);
    colors.push_back({rgb[0], rgb[1], rgb[2]});
  }
  const nlohmann::json expected = {{"model", "model.glb"},
                                   {"camera", view.name},
                                   {"width", c.width},
                                   {"height", c.height},
                                   {"labels", "labels.bin"},
                                   {"side_colors", colors},
                                   {"num_vertices", summary.num_vertices},
                                   {"num_cameras", summary.num_cameras}};
  std::ofstream(out / "expected.json") << expected.dump(2) << "\n";
  std::printf("write_test_glb: %s (%zu bytes, %zu vertices, %zu primitives, %zu cameras)\n",
              (out / "model.glb").c_str(), summary.file_bytes, summary.num_vertices,
              summary.num_primitives, summary.num_cameras);
  return 0;
}
