#include "core/sfm/model_merger.h"

#include "core/scene/synthetic.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <random>
#include <set>

namespace reconduit {
namespace {

Similarity3 Inverse(const Similarity3& s) {
  Similarity3 inverse;
  inverse.scale = 1.0 / s.scale;
  inverse.rotation = s.rotation.transpose();
  inverse.translation = -(inverse.rotation * s.translation) / s.scale;
  return inverse;
}

// A known similarity: scale 2.5, a rotation about a skew axis, an offset.
Similarity3 KnownSimilarity() {
  Similarity3 s;
  s.scale = 2.5;
  s.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, -0.5).normalized()).toRotationMatrix();
  s.translation = Eigen::Vector3d(3, -1, 4);
  return s;
}

struct ModelNoise {
  double point = 0.0;   // Standard deviation of point positions, scene units.
  double center = 0.0;  // ... of camera centres.
  std::uint64_t seed = 1;
};

// The scene's photos `images` as a model in the frame `model_from_world` (the ground truth's
// poses and points, with noise): keypoints are the scene's (noisy) observations, every point
// seen by two of the photos is a point of the model.
Reconstruction ModelOf(const SyntheticScene& scene,
                       const std::set<int>& images,
                       const Similarity3& model_from_world,
                       const ModelNoise& noise = {}) {
  std::mt19937_64 random(noise.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  auto jitter = [&](double sigma) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) v[k] = sigma * gauss(random);
    return v;
  };
  Reconstruction model;
  std::map<int, std::vector<Observation>> seen;  // Scene point -> observations.
  for (int id : images) {
    const SyntheticImage& source = scene.images[id];
    model.cameras[0] = source.camera;
    RegisteredImage image;
    image.image_id = id;
    image.camera_id = 0;
    image.name = "view" + std::to_string(id);
    Rigid3d pose = source.cam_from_world;
    pose.translation -= pose.rotation * jitter(noise.center);  // Moves the centre.
    image.cam_from_world = model_from_world.MapPose(pose);
    for (int k = 0; k < static_cast<int>(source.observations.size()); ++k) {
      image.keypoints.push_back(source.observations[k].pixel);
      const SyntheticObservation& o = source.observations[k];
      if (!o.is_outlier && o.point_index >= 0) seen[o.point_index].push_back({id, k});
    }
    image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
    model.images[id] = std::move(image);
  }
  for (const auto& [index, observations] : seen) {
    if (observations.size() < 2) continue;
    model.AddPoint(model_from_world * (scene.points3D[index] + jitter(noise.point)), observations);
  }
  return model;
}

KeypointTracks TracksOf(const SyntheticScene& scene) {
  KeypointTracks tracks;
  for (int id = 0; id < static_cast<int>(scene.images.size()); ++id) {
    for (const SyntheticObservation& o : scene.images[id].observations) {
      tracks[id].push_back(o.is_outlier ? -1 : o.point_index);
    }
  }
  return tracks;
}

SyntheticScene Ring(SyntheticCameraLayout layout = SyntheticCameraLayout::kRing) {
  SyntheticSceneOptions options;
  options.num_cameras = 10;
  options.layout = layout;
  options.num_points = 600;
  options.pixel_noise_stddev = 0.5;
  options.seed = 21;
  return SynthesizeScene(options);
}

std::set<int> Range(int first, int last) {
  std::set<int> ids;
  for (int k = first; k <= last; ++k) ids.insert(k);
  return ids;
}

void ExpectSimilarity(const Similarity3& got, const Similarity3& want, double tolerance) {
  EXPECT_NEAR(got.scale / want.scale, 1.0, tolerance);
  EXPECT_LT(Eigen::AngleAxisd(got.rotation * want.rotation.transpose()).angle(), tolerance);
  EXPECT_LT((got.translation - want.translation).norm(), tolerance * want.translation.norm());
}

TEST(ModelMergerOptions, DefaultsAreValidAndBadOnesNamed) {
  std::string error;
  EXPECT_TRUE(ModelMergerOptions().Check(&error)) << error;
  ModelMergerOptions bad;
  bad.min_inliers = 2;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("min_inliers"), std::string::npos);
}

TEST(Similarity3, MapPoseKeepsProjections) {
  const Similarity3 s = KnownSimilarity();
  const Rigid3d pose = Rigid3d::LookAt({4, 1, 2}, {0, 0, 0});
  const Eigen::Vector3d x(0.3, -0.2, 0.5);
  const Eigen::Vector3d before = pose * x;
  const Eigen::Vector3d after = s.MapPose(pose) * (s * x);
  EXPECT_LT((before.hnormalized() - after.hnormalized()).norm(), 1e-12);
  EXPECT_NEAR(after.z() / before.z(), s.scale, 1e-12);
}

TEST(AlignModels, ExactSimilarity) {
  const SyntheticScene scene = Ring();
  const Reconstruction a = ModelOf(scene, Range(0, 5), Similarity3());
  const Similarity3 truth = KnownSimilarity();  // a_from_b
  const Reconstruction b = ModelOf(scene, Range(3, 9), Inverse(truth));
  const ModelCorrespondences c = FindModelCorrespondences(a, b, nullptr);
  EXPECT_EQ(c.images, (std::vector<int>{3, 4, 5}));
  EXPECT_GT(c.points.size(), 50u);
  std::string why;
  const auto alignment = AlignModels(a, b, c, ModelMergerOptions(), &why);
  ASSERT_TRUE(alignment) << why;
  ExpectSimilarity(alignment->a_from_b, truth, 1e-9);
  EXPECT_EQ(alignment->num_inlier_images, 3);
  EXPECT_EQ(alignment->num_inlier_points, static_cast<int>(c.points.size()));
}

TEST(AlignModels, NoisyPositionsAndOutlierCorrespondences) {
  const SyntheticScene scene = Ring();
  const ModelNoise noise{0.01, 0.01, 3};  // Scene radius 1, cameras 6 away.
  const Reconstruction a = ModelOf(scene, Range(0, 6), Similarity3(), noise);
  const Similarity3 truth = KnownSimilarity();
  Reconstruction b = ModelOf(scene, Range(3, 9), Inverse(truth), {0.01, 0.01, 4});
  const ModelCorrespondences c = FindModelCorrespondences(a, b, nullptr);
  // A third of B's shared points and one shared photo moved far away.
  std::set<int> moved;
  for (std::size_t k = 0; k < c.points.size(); k += 3) {
    b.points.at(c.points[k].second).xyz_in_world += Eigen::Vector3d(1.0, -0.7, 0.4);
    moved.insert(static_cast<int>(k));
  }
  b.images.at(4).cam_from_world.translation += Eigen::Vector3d(0.5, 0.5, 0);
  std::string why;
  const auto alignment = AlignModels(a, b, c, ModelMergerOptions(), &why);
  ASSERT_TRUE(alignment) << why;
  ExpectSimilarity(alignment->a_from_b, truth, 0.01);
  EXPECT_EQ(alignment->num_inlier_images, static_cast<int>(c.images.size()) - 1);
  for (std::size_t k = 0; k < c.points.size(); ++k) {
    if (moved.count(static_cast<int>(k))) {
      EXPECT_FALSE(alignment->point_inliers[k]) << k;
    }
  }
  EXPECT_GT(alignment->num_inlier_points, 0.6 * c.points.size());
}

TEST(AlignModels, RefusesTooFewSharedItems) {
  const SyntheticScene scene = Ring();
  const Reconstruction a = ModelOf(scene, Range(0, 3), Similarity3());
  Reconstruction b = ModelOf(scene, Range(3, 7), Inverse(KnownSimilarity()));
  // B keeps only the points its other photos see: it shares photo 3 and nothing else.
  for (int kp = 0; kp < static_cast<int>(b.images.at(3).point_for_keypoint.size()); ++kp) {
    const int point = b.images.at(3).point_for_keypoint[kp];
    if (point != kInvalidId) b.DeleteObservation(point, {3, kp});
  }
  const ModelCorrespondences c = FindModelCorrespondences(a, b, nullptr);
  EXPECT_EQ(c.images.size(), 1u);
  EXPECT_TRUE(c.points.empty());
  std::string why;
  EXPECT_FALSE(AlignModels(a, b, c, ModelMergerOptions(), &why));
  EXPECT_NE(why.find("too few"), std::string::npos) << why;
}

TEST(AlignModels, RefusesInconsistentCorrespondences) {
  const SyntheticScene scene = Ring();
  const Reconstruction a = ModelOf(scene, Range(0, 5), Similarity3());
  Reconstruction b = ModelOf(scene, Range(3, 9), Inverse(KnownSimilarity()));
  // B's points scrambled: every shared point is somewhere else; the photos still agree, but
  // they are 3 of 100+.
  std::vector<Eigen::Vector3d> positions;
  for (const auto& [id, point] : b.points) positions.push_back(point.xyz_in_world);
  std::mt19937_64 random(5);
  std::shuffle(positions.begin(), positions.end(), random);
  int k = 0;
  for (auto& [id, point] : b.points) point.xyz_in_world = positions[k++];
  const ModelCorrespondences c = FindModelCorrespondences(a, b, nullptr);
  std::string why;
  EXPECT_FALSE(AlignModels(a, b, c, ModelMergerOptions(), &why));
  EXPECT_NE(why.find("agree"), std::string::npos) << why;
}

// Models that share only photos whose centres lie on a line (no shared points): the photos'
// orientations fix the rotation about the line.
TEST(AlignModels, CollinearSharedPhotosWithoutPoints) {
  const SyntheticScene scene = Ring(SyntheticCameraLayout::kLine);
  const Reconstruction a = ModelOf(scene, Range(0, 6), Similarity3());
  Reconstruction b = ModelOf(scene, Range(3, 9), Inverse(KnownSimilarity()));
  std::vector<int> all;
  for (const auto& [id, point] : b.points) all.push_back(id);
  for (int id : all) b.DeletePoint(id);
  const ModelCorrespondences c = FindModelCorrespondences(a, b, nullptr);
  ASSERT_EQ(c.images.size(), 4u);
  ASSERT_TRUE(c.points.empty());
  ModelMergerOptions options;
  options.min_inliers = 3;
  std::string why;
  const auto alignment = AlignModels(a, b, c, options, &why);
  ASSERT_TRUE(alignment) << why;
  ExpectSimilarity(alignment->a_from_b, KnownSimilarity(), 1e-9);
}

// Shared points only (models linked by tracks, no common photo): coplanar points fix the
// similarity, collinear ones do not.
TEST(AlignModels, SharedPointsCoplanarOrCollinear) {
  const SyntheticScene scene = Ring();
  const KeypointTracks tracks = TracksOf(scene);
  const Reconstruction a = ModelOf(scene, Range(0, 4), Similarity3());
  Reconstruction b = ModelOf(scene, Range(5, 9), Inverse(KnownSimilarity()));
  EXPECT_TRUE(FindModelCorrespondences(a, b, nullptr).points.empty());
  ModelCorrespondences c = FindModelCorrespondences(a, b, &tracks);
  EXPECT_TRUE(c.images.empty());
  ASSERT_GE(c.points.size(), 20u);
  // Flatten the shared points onto the plane z = 0 of A (in both models).
  const Similarity3 b_from_a = Inverse(KnownSimilarity());
  Reconstruction flat_a = a, flat_b = b;
  for (const auto& [pa, pb] : c.points) {
    Eigen::Vector3d& x = flat_a.points.at(pa).xyz_in_world;
    x.z() = 0;
    flat_b.points.at(pb).xyz_in_world = b_from_a * x;
  }
  std::string why;
  const auto plane = AlignModels(flat_a, flat_b, c, ModelMergerOptions(), &why);
  ASSERT_TRUE(plane) << why;
  ExpectSimilarity(plane->a_from_b, KnownSimilarity(), 1e-9);
  // ... and onto a line.
  for (const auto& [pa, pb] : c.points) {
    Eigen::Vector3d& x = flat_a.points.at(pa).xyz_in_world;
    x.y() = 0.5 * x.x();
    flat_b.points.at(pb).xyz_in_world = b_from_a * x;
  }
  EXPECT_FALSE(AlignModels(flat_a, flat_b, c, ModelMergerOptions(), &why));
  EXPECT_NE(why.find("degenerate"), std::string::npos) << why;
}

TEST(MergeModels, JoinsEveryPhotoAndFusesSharedPoints) {
  const SyntheticScene scene = Ring();
  const ModelNoise noise{0.002, 0.002, 7};
  Reconstruction a = ModelOf(scene, Range(0, 5), Similarity3(), noise);
  const Reconstruction b = ModelOf(scene, Range(3, 9), Inverse(KnownSimilarity()), noise);
  const std::size_t points_a = a.points.size();
  BundleAdjustmentOptions ba;
  ba.num_threads = 1;
  ba.loss = BundleAdjustmentLoss::kCauchy;
  const MergeSummary summary = MergeModels(b, nullptr, ModelMergerOptions(), ba, CancelToken(), &a);
  ASSERT_TRUE(summary.merged) << summary.message;
  EXPECT_NE(summary.message.find("merged model B (7 photos) into A (6 photos) via 3 shared photos"),
            std::string::npos)
      << summary.message;
  EXPECT_EQ(a.images.size(), 10u);
  EXPECT_EQ(summary.num_images, 10);
  // One point per scene point seen twice: the shared ones were fused, not duplicated.
  std::set<int> seen_twice;
  std::map<int, int> count;
  for (int id = 0; id < 10; ++id) {
    for (const SyntheticObservation& o : scene.images[id].observations) {
      if (!o.is_outlier && o.point_index >= 0) ++count[o.point_index];
    }
  }
  for (const auto& [p, n] : count) {
    if (n >= 2) seen_twice.insert(p);
  }
  EXPECT_GE(a.points.size(), points_a);
  EXPECT_LE(a.points.size(), seen_twice.size());
  EXPECT_GT(a.points.size(), 0.95 * seen_twice.size());
  EXPECT_LT(a.MeanReprojectionError(), 1.0);
  // B's photos sit where the ground truth puts them (A's frame is the world's, up to the
  // gauge the adjustment fixed on A's noisy first two photos): within 1 % of the distance.
  for (int id = 6; id <= 9; ++id) {
    const double error = (a.images.at(id).cam_from_world.CenterInWorld() -
                          scene.images[id].cam_from_world.CenterInWorld())
                             .norm();
    EXPECT_LT(error, 0.06) << id;
  }
}

// The courtyard: a loop of 19 photos reconstructed as two overlapping models of 15
// and 17 photos that share 13 (here: 0..14 and 2..18, B in another frame, both noisy).
TEST(MergeModels, OverlappingLoopModelsKeepEveryPhoto) {
  SyntheticSceneOptions options;
  options.num_cameras = 19;
  options.num_points = 800;
  options.pixel_noise_stddev = 0.5;
  options.outlier_fraction = 0.02;
  options.seed = 19;
  const SyntheticScene scene = SynthesizeScene(options);
  Reconstruction a = ModelOf(scene, Range(0, 14), Similarity3(), {0.003, 0.003, 8});
  const Reconstruction b =
      ModelOf(scene, Range(2, 18), Inverse(KnownSimilarity()), {0.003, 0.003, 9});
  BundleAdjustmentOptions ba;
  ba.num_threads = 1;
  ba.loss = BundleAdjustmentLoss::kCauchy;
  const MergeSummary summary = MergeModels(b, nullptr, ModelMergerOptions(), ba, CancelToken(), &a);
  ASSERT_TRUE(summary.merged) << summary.message;
  EXPECT_EQ(summary.alignment.num_images, 13);
  EXPECT_EQ(summary.alignment.num_inlier_images, 13);
  EXPECT_EQ(a.images.size(), 19u);
  EXPECT_LT(a.MeanReprojectionError(), 1.0);
  for (int id : {15, 16, 17, 18}) {
    const double error = (a.images.at(id).cam_from_world.CenterInWorld() -
                          scene.images[id].cam_from_world.CenterInWorld())
                             .norm();
    EXPECT_LT(error, 0.01 * options.camera_distance) << id;
  }
}

TEST(MergeModels, RefusedMergeLeavesAUnchanged) {
  const SyntheticScene scene = Ring();
  Reconstruction a = ModelOf(scene, Range(0, 3), Similarity3());
  const Reconstruction b = ModelOf(scene, Range(6, 9), Inverse(KnownSimilarity()));
  const std::size_t points = a.points.size();
  BundleAdjustmentOptions ba;
  ba.num_threads = 1;
  const MergeSummary summary = MergeModels(b, nullptr, ModelMergerOptions(), ba, CancelToken(), &a);
  EXPECT_FALSE(summary.merged);
  EXPECT_NE(summary.message.find("not merged"), std::string::npos);
  EXPECT_EQ(a.images.size(), 4u);
  EXPECT_EQ(a.points.size(), points);
}

}  // namespace
}  // namespace reconduit
