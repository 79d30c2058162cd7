#include "core/io/bundler.h"

#include "core/io/file_util.h"
#include "core/io/sparse_model_test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using testing_util::DistortedSceneOptions;
using testing_util::FreshTestFolder;
using testing_util::SyntheticReconstruction;

// bundle.out parsed independently of the writer, following the Bundler manual.
struct BundlerCamera {
  double f = 0, k1 = 0, k2 = 0;
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
};
struct BundlerView {
  int camera = -1, key = -1;
  Eigen::Vector2d xy;
};
struct BundlerPoint {
  Eigen::Vector3d xyz;
  int rgb[3] = {0, 0, 0};
  std::vector<BundlerView> views;
};
struct BundleFile {
  std::vector<BundlerCamera> cameras;
  std::vector<BundlerPoint> points;
};

BundleFile ParseBundle(const std::string& text) {
  std::istringstream in(text);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "# Bundle file v0.3");
  BundleFile bundle;
  int num_cameras = 0, num_points = 0;
  in >> num_cameras >> num_points;
  bundle.cameras.resize(num_cameras);
  for (BundlerCamera& c : bundle.cameras) {
    in >> c.f >> c.k1 >> c.k2;
    for (int i = 0; i < 3; ++i) in >> c.r(i, 0) >> c.r(i, 1) >> c.r(i, 2);
    in >> c.t.x() >> c.t.y() >> c.t.z();
  }
  bundle.points.resize(num_points);
  for (BundlerPoint& p : bundle.points) {
    in >> p.xyz.x() >> p.xyz.y() >> p.xyz.z() >> p.rgb[0] >> p.rgb[1] >> p.rgb[2];
    int n = 0;
    in >> n;
    p.views.resize(n);
    for (BundlerView& v : p.views) in >> v.camera >> v.key >> v.xy.x() >> v.xy.y();
  }
  EXPECT_FALSE(in.fail()) << "bundle.out is truncated or malformed";
  std::string rest;
  in >> rest;
  EXPECT_TRUE(rest.empty()) << "trailing data: " << rest;
  return bundle;
}

// Bundler's documented projection: P = R X + t, p = -P / P.z, p' = f r(p) p, in pixels from
// the image centre with y up.
Eigen::Vector2d BundlerProject(const BundlerCamera& c, const Eigen::Vector3d& x) {
  const Eigen::Vector3d p_cam = c.r * x + c.t;
  const Eigen::Vector2d p = -p_cam.head<2>() / p_cam.z();
  const double n2 = p.squaredNorm();
  return c.f * (1.0 + c.k1 * n2 + c.k2 * n2 * n2) * p;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

class BundlerTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = FreshTestFolder(); }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes `rec` and parses it back; also checks list.txt against the camera order.
  BundleFile WriteAndParse(const Reconstruction& rec) {
    const Status status = WriteBundler(dir_ / "bundle", rec);
    EXPECT_TRUE(status.ok()) << status;
    const auto list = Lines(*ReadFile(dir_ / "bundle" / "list.txt"));
    BundleFile bundle = ParseBundle(*ReadFile(dir_ / "bundle" / "bundle.out"));
    EXPECT_EQ(list.size(), rec.images.size());
    EXPECT_EQ(bundle.cameras.size(), rec.images.size());
    std::size_t i = 0;
    for (const auto& [id, image] : rec.images) {
      if (i < list.size()) {
        EXPECT_EQ(list[i], image.name) << "camera " << i;
      }
      ++i;
    }
    return bundle;
  }

  fs::path dir_;
};

TEST_F(BundlerTest, ProjectionWithBundlerEquationsReproducesEveryKeypoint) {
  SyntheticSceneOptions options = DistortedSceneOptions();
  options.pixel_noise_stddev = 0.0;         // Keypoints are exact projections...
  options.principal_point_variation = 0.0;  // ...through a principal point Bundler can hold.
  const Reconstruction rec = SyntheticReconstruction(options);
  const BundleFile bundle = WriteAndParse(rec);
  std::vector<const RegisteredImage*> by_camera;
  for (const auto& [id, image] : rec.images) by_camera.push_back(&image);

  ASSERT_EQ(bundle.points.size(), rec.points.size());
  std::size_t checked = 0;
  auto point_it = rec.points.begin();
  for (const BundlerPoint& p : bundle.points) {
    const int point_id = point_it->first;
    const Point3D& point = point_it->second;
    ++point_it;
    EXPECT_EQ(p.xyz, point.xyz_in_world);
    EXPECT_EQ(p.rgb[0], point.rgb[0]);
    EXPECT_EQ(p.rgb[2], point.rgb[2]);
    ASSERT_EQ(p.views.size(), point.observations.size());
    for (const BundlerView& v : p.views) {
      ASSERT_GE(v.camera, 0);
      ASSERT_LT(v.camera, static_cast<int>(by_camera.size()));
      const RegisteredImage& image = *by_camera[v.camera];
      const Camera& camera = rec.cameras.at(image.camera_id);
      // Our keypoint in Bundler's frame: centred, y up.
      const Eigen::Vector2d& pixel = image.keypoints.at(v.key);
      const Eigen::Vector2d centred(pixel.x() - (camera.width - 1) / 2.0,
                                    (camera.height - 1) / 2.0 - pixel.y());
      EXPECT_LT((v.xy - centred).norm(), 1e-9) << "the written key is the keypoint";
      const Eigen::Vector2d projected = BundlerProject(bundle.cameras[v.camera], p.xyz);
      EXPECT_LT((projected - centred).norm(), 1e-6)
          << "image " << image.image_id << " key " << v.key;
      EXPECT_EQ(image.point_for_keypoint[v.key], point_id);
      ++checked;
    }
  }
  EXPECT_EQ(checked, rec.NumObservations());
  EXPECT_GT(checked, 300u);

  // Rotations are proper and the camera centre -Rᵀt is ours.
  std::size_t i = 0;
  for (const auto& [id, image] : rec.images) {
    const BundlerCamera& c = bundle.cameras[i++];
    EXPECT_NEAR(c.r.determinant(), 1.0, 1e-12);
    EXPECT_LT((-c.r.transpose() * c.t - image.cam_from_world.CenterInWorld()).norm(), 1e-9);
    EXPECT_EQ(c.f, rec.cameras.at(image.camera_id).focal);
    EXPECT_EQ(c.k1, rec.cameras.at(image.camera_id).k1);
    EXPECT_EQ(c.k2, rec.cameras.at(image.camera_id).k2);
  }
}

// Bundler has no principal point; the documented consequence is a constant offset.
TEST_F(BundlerTest, OffCentrePrincipalPointShiftsProjectionsByTheOffset) {
  SyntheticSceneOptions options = DistortedSceneOptions();
  options.pixel_noise_stddev = 0.0;
  options.principal_point_variation = 8.0;
  const Reconstruction rec = SyntheticReconstruction(options);
  const BundleFile bundle = WriteAndParse(rec);
  std::vector<const RegisteredImage*> by_camera;
  for (const auto& [id, image] : rec.images) by_camera.push_back(&image);
  double largest_offset = 0.0;
  for (const BundlerPoint& p : bundle.points) {
    for (const BundlerView& v : p.views) {
      const Camera& camera = rec.cameras.at(by_camera[v.camera]->camera_id);
      const Eigen::Vector2d offset(camera.cx - (camera.width - 1) / 2.0,
                                   (camera.height - 1) / 2.0 - camera.cy);
      largest_offset = std::max(largest_offset, offset.norm());
      EXPECT_LT((BundlerProject(bundle.cameras[v.camera], p.xyz) + offset - v.xy).norm(), 1e-6);
    }
  }
  EXPECT_GT(largest_offset, 1.0) << "the scene must have off-centre principal points";
}

TEST_F(BundlerTest, EmptyReconstruction) {
  ASSERT_TRUE(WriteBundler(dir_, Reconstruction()).ok());
  EXPECT_EQ(*ReadFile(dir_ / "bundle.out"), "# Bundle file v0.3\n0 0\n");
  EXPECT_EQ(*ReadFile(dir_ / "list.txt"), "");
}

TEST_F(BundlerTest, RefusesNamesWithLineBreaks) {
  Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  rec.images.at(2).name = "a\r\nb.jpg";
  EXPECT_EQ(WriteBundler(dir_, rec).code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reconduit
