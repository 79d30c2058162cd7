#include "core/sfm/incremental_mapper.h"

#include "core/scene/synthetic.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace reconduit {
namespace {

// Mapper input straight from a synthetic scene: keypoints are the (noisy) observations, every
// pair's correspondences are its matches (outliers included), all pairs epipolar.
MapperInput InputFromScene(const SyntheticScene& scene, double focal_guess) {
  MapperInput input;
  input.cameras[0] = scene.images[0].camera;
  input.cameras[0].focal = focal_guess;
  std::vector<PairMatches> pair_matches;
  for (int i = 0; i < static_cast<int>(scene.images.size()); ++i) {
    MapperImage image;
    image.name = "view" + std::to_string(i);
    image.camera_id = 0;
    for (const SyntheticObservation& o : scene.images[i].observations)
      image.keypoints.push_back(o.pixel);
    input.images[i] = std::move(image);
  }
  for (int i = 0; i < static_cast<int>(scene.images.size()); ++i) {
    for (int j = i + 1; j < static_cast<int>(scene.images.size()); ++j) {
      MapperPair pair;
      pair.image1 = i;
      pair.image2 = j;
      pair.epipolar = true;
      for (const SyntheticCorrespondence& c : FindCorrespondences(scene, i, j)) {
        pair.matches.push_back({c.observation1, c.observation2});
      }
      pair.num_inliers_F = static_cast<int>(pair.matches.size());
      if (pair.matches.size() < 20) continue;
      pair_matches.push_back({i, j, pair.matches});
      input.pairs.push_back(std::move(pair));
    }
  }
  input.tracks = BuildTracks(pair_matches);
  return input;
}

struct Errors {
  double max_center = 0.0;        // Scene units after a similarity alignment.
  double max_rotation_deg = 0.0;  // After alignment.
};

Errors Compare(const Reconstruction& model, const SyntheticScene& scene) {
  const int n = static_cast<int>(model.images.size());
  Eigen::Matrix3Xd estimated(3, n), expected(3, n);
  std::vector<int> ids;
  int k = 0;
  for (const auto& [id, image] : model.images) {
    estimated.col(k) = image.cam_from_world.CenterInWorld();
    expected.col(k) = scene.images[id].cam_from_world.CenterInWorld();
    ids.push_back(id);
    ++k;
  }
  const Eigen::Matrix4d sim = Eigen::umeyama(estimated, expected, true);
  const double scale = sim.topLeftCorner<3, 3>().col(0).norm();
  const Eigen::Matrix3d world_rotation = sim.topLeftCorner<3, 3>() / scale;
  Errors errors;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d aligned = (sim * estimated.col(i).homogeneous()).head<3>();
    errors.max_center = std::max(errors.max_center, (aligned - expected.col(i)).norm());
    const Eigen::Matrix3d r = model.images.at(ids[i]).cam_from_world.rotation.toRotationMatrix() *
                              world_rotation.transpose();
    const double angle =
        Eigen::AngleAxisd(
            r * scene.images[ids[i]].cam_from_world.rotation.toRotationMatrix().transpose())
            .angle();
    errors.max_rotation_deg = std::max(errors.max_rotation_deg, angle * 180.0 / M_PI);
  }
  return errors;
}

TEST(IncrementalMapperOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(IncrementalMapperOptions().Check(&error)) << error;
  IncrementalMapperOptions bad;
  bad.global_ba_growth = 1.0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("global_ba_growth"), std::string::npos);
}

TEST(ReconstructIncrementally, RecoversCamerasAndFocalWithNoiseAndOutliers) {
  SyntheticSceneOptions options;
  options.num_cameras = 10;
  options.num_points = 1500;
  options.focal = 800;
  options.width = 1024;
  options.height = 768;
  options.k1 = -0.05;
  options.pixel_noise_stddev = 0.5;
  options.outlier_fraction = 0.05;
  options.seed = 7;
  const SyntheticScene scene = SynthesizeScene(options);
  const MapperInput input = InputFromScene(scene, /*focal_guess=*/800 * 1.03);

  Progress progress;
  MapperSummary summary;
  const auto models = ReconstructIncrementally(input, IncrementalMapperOptions(), progress,
                                               CancelToken(), &summary);
  ASSERT_EQ(models.size(), 1u);
  const Reconstruction& model = models.front();
  EXPECT_EQ(model.images.size(), 10u);
  EXPECT_EQ(summary.num_registered, 10);
  const Errors errors = Compare(model, scene);
  EXPECT_LT(errors.max_center, 0.02 * options.camera_distance);
  EXPECT_LT(errors.max_rotation_deg, 0.3);
  EXPECT_NEAR(model.cameras.at(0).focal, 800.0, 0.01 * 800.0) << "refined from a 3 % error";
  EXPECT_NEAR(model.cameras.at(0).k1, -0.05, 0.02);
  EXPECT_LT(model.MeanReprojectionError(), 1.0);
  EXPECT_GT(model.points.size(), 1000u);
}

TEST(ReconstructIncrementally, PureRotationCannotInitialise) {
  SyntheticSceneOptions options;
  options.layout = SyntheticCameraLayout::kPureRotation;
  options.num_cameras = 5;
  options.num_points = 600;
  options.pixel_noise_stddev = 0.5;
  options.seed = 3;
  const SyntheticScene scene = SynthesizeScene(options);
  const MapperInput input = InputFromScene(scene, options.focal);
  Progress progress;
  const auto models =
      ReconstructIncrementally(input, IncrementalMapperOptions(), progress, CancelToken());
  EXPECT_TRUE(models.empty()) << "no parallax: no initial pair may be accepted";
}

TEST(ReconstructIncrementally, Cancellation) {
  SyntheticSceneOptions options;
  options.seed = 1;
  const SyntheticScene scene = SynthesizeScene(options);
  const MapperInput input = InputFromScene(scene, options.focal);
  CancelToken cancel;
  cancel.RequestCancel();
  Progress progress;
  EXPECT_THROW(ReconstructIncrementally(input, IncrementalMapperOptions(), progress, cancel),
               CancelledError);
}

}  // namespace
}  // namespace reconduit
