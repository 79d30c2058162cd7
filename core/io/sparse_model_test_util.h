// Test helpers for the sparse-model readers and writers: a Reconstruction built from a
// synthetic scene (core/scene/synthetic.h), temporary folders and field-by-field comparison.
// Header-only; used by the *_test.cc files of core/io only.
#ifndef RECONDUIT_CORE_IO_SPARSE_MODEL_TEST_UTIL_H_
#define RECONDUIT_CORE_IO_SPARSE_MODEL_TEST_UTIL_H_

#include "core/scene/reconstruction.h"
#include "core/scene/synthetic.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>
#include <vector>

namespace reconduit::testing_util {

// Options of the default test scene: 6 images each with its own distorted camera (focal,
// principal point and distortion vary), noisy keypoints, some outliers (keypoints that observe
// no point).
inline SyntheticSceneOptions DistortedSceneOptions() {
  SyntheticSceneOptions options;
  options.num_cameras = 6;
  options.num_points = 150;
  options.width = 640;
  options.height = 480;
  options.focal = 520.0;
  options.k1 = -0.12;
  options.k2 = 0.03;
  options.shared_intrinsics = false;
  options.focal_variation = 0.05;
  options.principal_point_variation = 6.0;
  options.distortion_variation = 0.02;
  options.pixel_noise_stddev = 0.4;
  options.outlier_fraction = 0.05;
  options.seed = 7;
  return options;
}

// A Reconstruction of the scene: image i has image_id i, camera_id from the scene and name
// "view_<i>.jpg" (image 1 gets a name with a space); its keypoints are the observed pixels,
// outliers included (they observe no point). Every point seen by at least two inlier
// observations becomes a point with a deterministic colour and error; every fifth is then
// deleted so the point ids have gaps.
inline Reconstruction SyntheticReconstruction(const SyntheticSceneOptions& options) {
  const SyntheticScene scene = SynthesizeScene(options);
  Reconstruction rec;
  std::vector<std::vector<Observation>> seen_by(scene.points3D.size());
  for (std::size_t i = 0; i < scene.images.size(); ++i) {
    const SyntheticImage& source = scene.images[i];
    rec.cameras[source.camera_id] = source.camera;
    RegisteredImage& image = rec.images[static_cast<int>(i)];
    image.image_id = static_cast<int>(i);
    image.camera_id = source.camera_id;
    image.name = i == 1 ? "view 1 (copy).jpg" : "view_" + std::to_string(i) + ".jpg";
    image.cam_from_world = source.cam_from_world;
    for (const SyntheticObservation& o : source.observations) {
      if (o.point_index >= 0) {
        seen_by[o.point_index].push_back(
            {static_cast<int>(i), static_cast<int>(image.keypoints.size())});
      }
      image.keypoints.push_back(o.pixel);
    }
    image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
  }
  std::vector<int> ids;
  for (std::size_t j = 0; j < scene.points3D.size(); ++j) {
    if (seen_by[j].size() < 2) continue;
    const int id = rec.AddPoint(scene.points3D[j], seen_by[j]);
    Point3D& point = rec.points.at(id);
    point.rgb = {static_cast<std::uint8_t>(j * 37 % 256), static_cast<std::uint8_t>(j * 91 % 256),
                 static_cast<std::uint8_t>(255 - j % 256)};
    point.error = 0.01 * static_cast<double>(j) + 1.0 / 3.0;
    ids.push_back(id);
  }
  for (std::size_t k = 0; k < ids.size(); k += 5) rec.DeletePoint(ids[k]);
  return rec;
}

// A fresh empty folder under the system's temporary folder, named after the running test.
inline std::filesystem::path FreshTestFolder() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("reconduit_io_" + std::string(info->test_suite_name()) + "_" +
                                     info->name() + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// The repository root (tests run there; RECONDUIT_SOURCE_DIR says so explicitly).
inline std::filesystem::path SourceDir() {
  const char* dir = std::getenv("RECONDUIT_SOURCE_DIR");
  return dir != nullptr ? std::filesystem::path(dir) : std::filesystem::current_path();
}

}  // namespace reconduit::testing_util

#endif  // RECONDUIT_CORE_IO_SPARSE_MODEL_TEST_UTIL_H_
