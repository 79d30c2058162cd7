#include "core/sfm/incremental_mapper.h"

#include "core/scene/synthetic.h"
#include "core/util/logging.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cstdint>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <set>

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
  IncrementalMapperOptions weak_above_bar;
  weak_above_bar.weak_initial_inliers = weak_above_bar.min_initial_inliers + 1;
  EXPECT_FALSE(weak_above_bar.Check(&error));
  EXPECT_NE(error.find("weak_initial_inliers"), std::string::npos);
  IncrementalMapperOptions loose_filter;
  loose_filter.final_outlier_multiple = 2.0;  // Would cut into Gaussian noise.
  EXPECT_FALSE(loose_filter.Check(&error));
  EXPECT_NE(error.find("final_outlier_multiple"), std::string::npos);
  IncrementalMapperOptions clear_above_bar;
  clear_above_bar.contradiction_clear_rotation_deg = 20.0;  // Above the 15 deg bar.
  EXPECT_FALSE(clear_above_bar.Check(&error));
  EXPECT_NE(error.find("contradiction_clear_rotation_deg"), std::string::npos);
  IncrementalMapperOptions no_margin;
  no_margin.contradiction_clear_margin = 0.0;
  EXPECT_FALSE(no_margin.Check(&error));
  EXPECT_NE(error.find("contradiction_clear_margin"), std::string::npos);
}

// 10 photos on a ring, 1500 points, f = 800 px, k1 = -0.05, 0.5 px noise, 5 % outliers.
SyntheticSceneOptions NoisyRingOptions() {
  SyntheticSceneOptions options;
  options.num_cameras = 10;
  options.num_points = 1500;
  options.focal = 800;
  options.width = 1024;
  options.height = 768;
  options.k1 = -0.05;
  options.pixel_noise_stddev = 0.5;
  options.outlier_fraction = 0.05;
  return options;
}

TEST(ReconstructIncrementally, RecoversCamerasAndFocalWithNoiseAndOutliers) {
  SyntheticSceneOptions options = NoisyRingOptions();
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

// The principal point's model selection (PrincipalPointMode::kAuto) on the 10-photo ring of
// the test above, once with the true principal point at the image centre and once 15 px off
// in x and y. The input cameras always start at the centre.
struct PrincipalPointRun {
  Camera camera;
  Errors errors;
  std::string decision;  // The mapper's log line about the principal point.
};

PrincipalPointRun RunWithPrincipalPoint(double offset, PrincipalPointMode mode) {
  SyntheticSceneOptions options = NoisyRingOptions();
  options.principal_point_offset = {offset, -offset};
  options.seed = 8;
  const SyntheticScene scene = SynthesizeScene(options);
  MapperInput input = InputFromScene(scene, 800 * 1.03);
  const Camera centred = Camera::FromFocal(options.width, options.height, 800);
  input.cameras[0].cx = centred.cx;
  input.cameras[0].cy = centred.cy;
  IncrementalMapperOptions mapper_options;
  mapper_options.principal_point = mode;
  Progress progress;
  MapperSummary summary;
  const auto models =
      ReconstructIncrementally(input, mapper_options, progress, CancelToken(), &summary);
  THROW_CHECK_EQ(models.size(), 1u);
  PrincipalPointRun run{models.front().cameras.at(0), Compare(models.front(), scene), ""};
  for (const std::string& line : summary.log) {
    if (line.starts_with("principal point")) run.decision = line;
  }
  return run;
}

TEST(ReconstructIncrementally, AutoPrincipalPointStaysAtACorrectCentre) {
  const PrincipalPointRun run = RunWithPrincipalPoint(0.0, PrincipalPointMode::kAuto);
  const Camera centred = Camera::FromFocal(1024, 768, 800);
  EXPECT_NE(run.decision.find("kept at the centre"), std::string::npos) << run.decision;
  EXPECT_EQ(run.camera.cx, centred.cx);
  EXPECT_EQ(run.camera.cy, centred.cy);
  EXPECT_LT(run.errors.max_rotation_deg, 0.3);
}

TEST(ReconstructIncrementally, AutoPrincipalPointFindsARealOffset) {
  const PrincipalPointRun held = RunWithPrincipalPoint(15.0, PrincipalPointMode::kCenter);
  const PrincipalPointRun free = RunWithPrincipalPoint(15.0, PrincipalPointMode::kAuto);
  const Camera truth = Camera::FromFocal(1024, 768, 800);
  EXPECT_NE(free.decision.find("refined"), std::string::npos) << free.decision;
  // A ring at one height pins the horizontal offset well and the vertical one less (a
  // vertical shift trades off against the common downward tilt).
  EXPECT_NEAR(free.camera.cx, truth.cx + 15.0, 2.0);
  EXPECT_NEAR(free.camera.cy, truth.cy - 15.0, 6.0);
  EXPECT_GT(held.errors.max_rotation_deg, 1.0) << "a wrong centre tilts the cameras";
  EXPECT_LT(free.errors.max_rotation_deg, 0.5 * held.errors.max_rotation_deg);
}

// Keeps the matches of `input` (built by InputFromScene) for which keep(image1, image2,
// source point) holds, drops pairs left with fewer than 20, and rebuilds the tracks.
template <typename Keep>
void FilterMatches(const SyntheticScene& scene, MapperInput* input, const Keep& keep) {
  std::vector<MapperPair> pairs;
  std::vector<PairMatches> pair_matches;
  for (MapperPair& pair : input->pairs) {
    std::erase_if(pair.matches, [&](const FeatureMatch& m) {
      const int point = scene.images[pair.image1].observations[m.index1].source_point;
      return !keep(pair.image1, pair.image2, point);
    });
    pair.num_inliers_F = static_cast<int>(pair.matches.size());
    if (pair.matches.size() < 20) continue;
    pair_matches.push_back({pair.image1, pair.image2, pair.matches});
    pairs.push_back(std::move(pair));
  }
  input->pairs = std::move(pairs);
  input->tracks = BuildTracks(pair_matches);
}

// A turntable-like ring as in templeSparseRing: 16 photos whose optical axes all meet at the
// object's centre, a narrow field of view (f = 2.4 x the longer side), no EXIF. Pairwise
// self-calibration is degenerate here (self_calibration_test.cc,
// AxesMeetingAtOnePointIsDegenerate), so the input focal is the sparse stage's fallback guess,
// 1.2 x the longer side: half the truth.
struct RingRun {
  double truth = 0.0;
  MapperSummary summary;
  std::vector<Reconstruction> models;
  Errors errors;
};

// A temple-like ring: `num_cameras` photos of 640 x 480 (focal 1536 px) on a circle around a
// small object, every optical axis through its centre, 0.3 px noise.
SyntheticSceneOptions TempleLikeRing(int num_cameras, int num_points, std::uint64_t seed) {
  SyntheticSceneOptions scene_options;
  scene_options.num_cameras = num_cameras;
  scene_options.num_points = num_points;
  scene_options.width = 640;
  scene_options.height = 480;
  scene_options.focal = 1536;
  scene_options.camera_distance = 6.0;
  scene_options.camera_height = 1.0;
  scene_options.scene_radius = 0.8;
  scene_options.target_jitter = 0.0;
  scene_options.pixel_noise_stddev = 0.3;
  scene_options.seed = seed;
  return scene_options;
}

RingRun ReconstructRingWhoseAxesMeet(int num_points, const IncrementalMapperOptions& options) {
  const SyntheticSceneOptions scene_options = TempleLikeRing(16, num_points, 12);
  const SyntheticScene scene = SynthesizeScene(scene_options);
  MapperInput input = InputFromScene(scene, /*focal_guess=*/1.2 * 640);
  // As on an object's surface, each point faces one way and is seen only from the photos
  // within 50 deg of that direction (photo k is at azimuth 22.5 k deg); a synthetic point is
  // otherwise visible in every photo, and all-to-all tracks would make the ring too easy.
  FilterMatches(scene, &input, [](int i, int j, int point) {
    const double facing = std::fmod(point * 137.5, 360.0);
    auto sees = [&](int k) { return std::abs(std::remainder(22.5 * k - facing, 360.0)) <= 50; };
    return sees(i) && sees(j);
  });
  input.uncertain_focal_camera_ids = {0};
  RingRun run;
  run.truth = scene_options.focal;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  if (!run.models.empty()) run.errors = Compare(run.models.front(), scene);
  return run;
}

TEST(ReconstructIncrementally, FocalSearchOnARingWhoseAxesMeet) {
  // 4,000 points, about 18,000 observations (twice templeSparseRing's). With 0.3 px noise the
  // data fix the focal of so narrow a ring only to a few tenths of a percent, however well the
  // search starts: seeds 11-13 end -0.37, +0.19 and -0.05 % off (with 2,000 points +0.26,
  // +0.49 and +0.74 %).
  const RingRun run = ReconstructRingWhoseAxesMeet(4000, IncrementalMapperOptions());
  ASSERT_EQ(run.models.size(), 1u);
  const Reconstruction& model = run.models.front();
  EXPECT_EQ(model.images.size(), 16u);
  ASSERT_TRUE(run.summary.searched_focal.count(0)) << "the focal was not searched";
  EXPECT_NEAR(run.summary.searched_focal.at(0), run.truth, 0.05 * run.truth)
      << "the start of the reconstruction, searched from half the truth";
  EXPECT_NEAR(model.cameras.at(0).focal, run.truth, 0.005 * run.truth);
  EXPECT_LT(run.errors.max_center, 0.005 * 6.0);
  EXPECT_LT(run.errors.max_rotation_deg, 0.2);
  bool converged = false;
  for (const std::string& line : run.summary.log)
    converged |= line.starts_with("focal search: converged");
  EXPECT_TRUE(converged) << "two trials agreed: no multi-start needed";
}

TEST(ReconstructIncrementally, FocalSearchMultiStart) {
  // A tolerance no two trials meet forces the multi-start over 0.5-5 x the longer side.
  IncrementalMapperOptions options;
  options.focal_search_tolerance = 1e-9;
  // Two rounds of the fixed-point iteration: later rounds can reach its fixed point exactly.
  options.focal_search_rounds = 2;
  const RingRun run = ReconstructRingWhoseAxesMeet(1000, options);
  ASSERT_EQ(run.models.size(), 1u);
  EXPECT_EQ(run.models.front().images.size(), 16u);
  int trials = 0;
  bool multi_start = false;
  for (const std::string& line : run.summary.log) {
    trials += line.starts_with("focal search: trial");
    multi_start |= line.starts_with("focal search: multi-start");
  }
  EXPECT_EQ(trials, 2 + options.focal_search_hypotheses);
  EXPECT_TRUE(multi_start);
  ASSERT_TRUE(run.summary.searched_focal.count(0));
  EXPECT_NEAR(run.summary.searched_focal.at(0), run.truth, 0.05 * run.truth);
  EXPECT_NEAR(run.models.front().cameras.at(0).focal, run.truth, 0.02 * run.truth);
}

// The first 8 temple photos: the pair ranked first as a seed is cut off from the others by a
// wide gap, so a trial from it stays at two photos and cannot refine the focal. The trial
// then moves on to the next seed (IncrementalMapperOptions::focal_search_seeds).
RingRun ReconstructRingWithAnIsolatedSeed(int focal_search_seeds) {
  const SyntheticSceneOptions scene_options = TempleLikeRing(12, 3000, 14);
  const SyntheticScene scene = SynthesizeScene(scene_options);
  MapperInput input = InputFromScene(scene, /*focal_guess=*/1.2 * 640);
  FilterMatches(scene, &input, [](int i, int j, int point) {
    const double facing = std::fmod(point * 137.5, 360.0);
    auto sees = [&](int k) { return std::abs(std::remainder(30.0 * k - facing, 360.0)) <= 50; };
    const bool cut_off = (i <= 1) != (j <= 1);  // Photos 0 and 1 see only each other.
    return sees(i) && sees(j) && !cut_off;
  });
  for (MapperPair& pair : input.pairs) {
    // Seeds are ranked by matches discounted by the homography's share: 0 + 1 first.
    pair.num_inliers_H = pair.image1 == 0 && pair.image2 == 1 ? 0 : pair.num_inliers_F;
  }
  input.uncertain_focal_camera_ids = {0};
  IncrementalMapperOptions options;
  options.focal_search_seeds = focal_search_seeds;
  RingRun run;
  run.truth = scene_options.focal;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  return run;
}

TEST(ReconstructIncrementally, FocalSearchMovesOnFromAnIsolatedSeed) {
  const RingRun one_seed = ReconstructRingWithAnIsolatedSeed(1);
  EXPECT_FALSE(one_seed.summary.searched_focal.count(0))
      << "every trial stays at the isolated pair: no focal";
  const RingRun run = ReconstructRingWithAnIsolatedSeed(3);
  ASSERT_TRUE(run.summary.searched_focal.count(0));
  EXPECT_NEAR(run.summary.searched_focal.at(0), run.truth, 0.05 * run.truth);
  ASSERT_FALSE(run.models.empty());
  EXPECT_EQ(run.models.front().images.size(), 10u);
  EXPECT_NEAR(run.models.front().cameras.at(0).focal, run.truth, 0.01 * run.truth);
}

TEST(ReconstructIncrementally, NoFocalSearchWithoutUncertainCameras) {
  SyntheticSceneOptions options;
  options.num_points = 300;
  options.seed = 2;
  const SyntheticScene scene = SynthesizeScene(options);
  const MapperInput input = InputFromScene(scene, options.focal);
  Progress progress;
  MapperSummary summary;
  ReconstructIncrementally(input, IncrementalMapperOptions(), progress, CancelToken(), &summary);
  EXPECT_TRUE(summary.searched_focal.empty());
  for (const std::string& line : summary.log) EXPECT_FALSE(line.starts_with("focal search"));
}

// A model can stop growing at a weak link that a later model crosses from the other side.
// Ten photos on an arc; photos 0 and 1 match each other and photo 2 only on the even points,
// photo 2 matches photos 3-9 only on the odd points. The first model starts from 0 + 1 (the
// pair scored best) and stops at {0, 1, 2}: the odd points photo 2 shares with the others
// have one registered view only. The next model starts among 3-9 and reaches photo 2 through
// the odd points, which it has triangulated. Photo 2 then belongs to the larger model only.
// An arc of 10 photos whose link between {0, 1, 2} and {3, ..., 9} is one-way: photo 2 shares
// points with 3..9 that 0 and 1 do not see, so the model seeded on 0 + 1 stops at 2 while the
// later model of 3..9 reaches 2 as well: two models sharing photo 2.
struct OneWayArc {
  SyntheticScene scene;
  MapperInput input;
};

OneWayArc MakeOneWayArc() {
  SyntheticSceneOptions options;
  options.num_cameras = 10;
  options.layout = SyntheticCameraLayout::kArc;
  options.arc_deg = 120;
  options.num_points = 1000;
  options.pixel_noise_stddev = 0.3;
  options.seed = 12;
  OneWayArc arc;
  arc.scene = SynthesizeScene(options);
  arc.input = InputFromScene(arc.scene, options.focal);
  FilterMatches(arc.scene, &arc.input, [](int i, int j, int point) {
    if (point % 100 == 0) return true;  // A few points everywhere: too few to cross on.
    if (j <= 2) return point % 2 == 0;  // Within {0, 1, 2}.
    if (i >= 3) return true;            // Within {3, ..., 9}.
    return i == 2 && point % 2 == 1;    // Across: 2 with 3..9 only.
  });
  for (MapperPair& pair : arc.input.pairs) {
    // Seeds are ranked by matches discounted by the homography's share: 0 + 1 first.
    pair.num_inliers_H = pair.image1 == 0 && pair.image2 == 1 ? 0 : pair.num_inliers_F;
  }
  return arc;
}

TEST(ReconstructIncrementally, APhotoOfAnEarlierModelJoinsALargerOne) {
  const OneWayArc arc = MakeOneWayArc();
  const SyntheticScene& scene = arc.scene;
  const MapperInput& input = arc.input;
  Progress progress;
  MapperSummary summary;
  // Registration by relative pose would cross the weak link from photo 2 (the test
  // WideGapsNeedRelativePoses): this test is about the later model's reach, without merging
  // (ModelsSharingAPhotoAreMerged).
  IncrementalMapperOptions no_relative;
  no_relative.relative_registration = false;
  no_relative.merge_models = false;
  const auto models =
      ReconstructIncrementally(input, no_relative, progress, CancelToken(), &summary);
  EXPECT_EQ(summary.num_merges, 0);
  ASSERT_EQ(models.size(), 2u);
  std::set<int> larger, smaller;
  for (const auto& [id, image] : models[0].images) larger.insert(id);
  for (const auto& [id, image] : models[1].images) smaller.insert(id);
  EXPECT_EQ(larger, (std::set<int>{2, 3, 4, 5, 6, 7, 8, 9}));
  EXPECT_EQ(smaller, (std::set<int>{0, 1}));
  EXPECT_EQ(summary.num_registered, 10);
  // The smaller model lost photo 2 and its observations, nothing else.
  for (const auto& [id, point] : models[1].points) {
    EXPECT_GE(point.observations.size(), 2u);
    for (const Observation& o : point.observations) EXPECT_TRUE(smaller.count(o.image_id));
  }
  EXPECT_LT(Compare(models[0], scene).max_center, 0.01 * SyntheticSceneOptions().camera_distance);
  // Every track seen by two photos of the larger model is a point of it, also the few the
  // first model had triangulated (a model does not inherit another's points).
  std::size_t tracks = 0;
  for (const Track& track : input.tracks) {
    int seen = 0;
    for (const Observation& o : track.observations) seen += larger.count(o.image_id);
    tracks += seen >= 2;
  }
  EXPECT_EQ(models[0].points.size(), tracks);
}

// The same two models, merged: they share photo 2 and the points it sees with both sides.
TEST(ReconstructIncrementally, ModelsSharingAPhotoAreMerged) {
  const OneWayArc arc = MakeOneWayArc();
  Progress progress;
  MapperSummary summary;
  IncrementalMapperOptions options;
  options.relative_registration = false;
  const auto models =
      ReconstructIncrementally(arc.input, options, progress, CancelToken(), &summary);
  ASSERT_EQ(models.size(), 1u);
  EXPECT_EQ(models[0].images.size(), 10u);
  EXPECT_EQ(summary.num_merges, 1);
  EXPECT_EQ(summary.num_registered, 10);
  int merged = 0;
  for (const std::string& line : summary.log) {
    merged += line.find("merged model B (3 photos) into A (8 photos) via 1 shared photos") !=
              std::string::npos;
  }
  EXPECT_EQ(merged, 1);
  const Errors errors = Compare(models[0], arc.scene);
  EXPECT_LT(errors.max_center, 0.01 * SyntheticSceneOptions().camera_distance);
  EXPECT_LT(errors.max_rotation_deg, 0.3);
  EXPECT_LT(models[0].MeanReprojectionError(), 1.0);
}

// Mean error of the relative rotations over all pairs of registered photos, degrees.
double RelativeRotationErrorDeg(const Reconstruction& model, const SyntheticScene& scene) {
  double sum = 0.0;
  int count = 0;
  for (auto i = model.images.begin(); i != model.images.end(); ++i) {
    for (auto j = std::next(i); j != model.images.end(); ++j) {
      const Eigen::Quaterniond estimated =
          i->second.cam_from_world.rotation * j->second.cam_from_world.rotation.inverse();
      const Eigen::Quaterniond truth = scene.images[i->first].cam_from_world.rotation *
                                       scene.images[j->first].cam_from_world.rotation.inverse();
      sum += estimated.angularDistance(truth) * 180.0 / M_PI;
      ++count;
    }
  }
  return count > 0 ? sum / count : 0.0;
}

// A loop of 24 photos 15 deg apart around a scene whose points each face one way (seen from
// the photos within 50 deg of it, as walls around a courtyard), 0.5 px noise, 2 % outliers.
//   kWeakLinks  the loop is cut between photos 5|6 and 17|18, where one match in 20 is kept
//               between the two neighbours only (fewer than registration needs): the mapper
//               grows two models, linked by those few tracks;
//   kOpen       the 5|6 link is dropped altogether and 17|18 kept whole: one open sequence of
//               the same 24 photos;
//   kBridge     as kWeakLinks, but photo 6 matches only one point in 16 with either side
//               (other points each side): it sees too few points of either model to be
//               registered, enough of the two merged.
enum class LoopCut { kWeakLinks, kOpen, kBridge };

// A synthetic scene and what the mapper made of it.
struct SceneRun {
  SyntheticScene scene;
  std::vector<Reconstruction> models;
  MapperSummary summary;
};

bool KeepLoopMatch(LoopCut cut, int i, int j, int point) {
  const double facing = std::fmod(point * 137.5, 360.0);
  auto sees = [&](int k) { return std::abs(std::remainder(15.0 * k - facing, 360.0)) <= 50; };
  if (!sees(i) || !sees(j)) return false;
  const int first = cut == LoopCut::kBridge ? 7 : 6;  // The first photo of the second side.
  auto side = [&](int k) { return k >= first && k <= 17; };
  if (cut == LoopCut::kBridge && (i == 6 || j == 6)) {
    return point % 16 == (side(i == 6 ? j : i) ? 0 : 8);
  }
  if (side(i) == side(j)) return true;
  const bool first_cut = i < first && side(j);
  if (cut == LoopCut::kOpen) return !first_cut;
  const bool neighbours = (i == first - 1 && j == first) || (i == 17 && j == 18);
  return neighbours && point % 20 == 0;
}

SceneRun ReconstructLoop(LoopCut cut, bool reregister = true) {
  SyntheticSceneOptions scene_options;
  scene_options.num_cameras = 24;
  scene_options.num_points = 2400;
  scene_options.camera_height = 1.0;
  scene_options.pixel_noise_stddev = 0.5;
  scene_options.outlier_fraction = 0.02;
  scene_options.seed = 31;
  SceneRun run;
  run.scene = SynthesizeScene(scene_options);
  MapperInput input = InputFromScene(run.scene, scene_options.focal);
  FilterMatches(run.scene, &input,
                [&](int i, int j, int point) { return KeepLoopMatch(cut, i, j, point); });
  IncrementalMapperOptions options;
  // More than the weak links give: they cannot be crossed by PnP, nor by relative pose.
  options.min_registration_points = 40;
  options.relative.min_pair_inliers = 40;
  options.reregister = reregister;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  return run;
}

TEST(ReconstructIncrementally, LoopCutInTwoIsMergedAlongItsTracks) {
  const SceneRun loop = ReconstructLoop(LoopCut::kWeakLinks);
  ASSERT_EQ(loop.models.size(), 1u);
  EXPECT_EQ(loop.models[0].images.size(), 24u);
  EXPECT_EQ(loop.summary.num_merges, 1);
  int merged = 0;
  for (const std::string& line : loop.summary.log) {
    merged += line.find("merged model B (12 photos) into A (12 photos) via 0 shared photos") !=
              std::string::npos;
  }
  EXPECT_EQ(merged, 1);
  const SceneRun open = ReconstructLoop(LoopCut::kOpen);
  ASSERT_EQ(open.models.size(), 1u);
  ASSERT_EQ(open.models[0].images.size(), 24u);
  EXPECT_EQ(open.summary.num_merges, 0);
  const double loop_error = RelativeRotationErrorDeg(loop.models[0], loop.scene);
  const double open_error = RelativeRotationErrorDeg(open.models[0], open.scene);
  std::cout << "relative rotation error: loop " << loop_error << " deg, open " << open_error
            << " deg\n";
  EXPECT_LT(loop_error, 1.5 * open_error + 0.01);
  EXPECT_LT(Compare(loop.models[0], loop.scene).max_center,
            0.01 * SyntheticSceneOptions().camera_distance);
}

// Photo 6 sees too few points of either model; after the merge, re-registration places it.
TEST(ReconstructIncrementally, APhotoLeftOutJoinsTheMergedModel) {
  const SceneRun without = ReconstructLoop(LoopCut::kBridge, /*reregister=*/false);
  ASSERT_FALSE(without.models.empty());
  EXPECT_EQ(without.summary.num_merges, 1);
  EXPECT_EQ(without.models[0].images.size(), 23u);
  EXPECT_FALSE(without.models[0].images.count(6));

  const SceneRun with = ReconstructLoop(LoopCut::kBridge);
  ASSERT_EQ(with.models.size(), 1u);
  EXPECT_EQ(with.models[0].images.size(), 24u);
  EXPECT_EQ(with.summary.num_reregistered, 1);
  int lines = 0;
  for (const std::string& line : with.summary.log) {
    lines += line.find(
                 "re-registration with the final intrinsics: 1 photo(s) joined a model "
                 "of 23") != std::string::npos;
  }
  EXPECT_EQ(lines, 1);
  const Errors errors = Compare(with.models[0], with.scene);
  EXPECT_LT(errors.max_center, 0.01 * SyntheticSceneOptions().camera_distance);
  EXPECT_LT(errors.max_rotation_deg, 0.5);
}

// A ring of 8 photos 45 deg apart (templeSparseRing every second photo): each point faces one
// way and is seen from the photos within 50 deg of it, so neighbours share about 60 matches
// but a photo sees only a handful of the points its registered neighbour triangulated: fewer
// than PnP needs (20). Registration by relative pose places each photo from its neighbour's
// two-view geometry with the scale from those few points.
SceneRun ReconstructWideRing(bool relative_registration) {
  SyntheticSceneOptions scene_options;
  scene_options.num_cameras = 8;
  scene_options.num_points = 400;
  scene_options.width = 640;
  scene_options.height = 480;
  scene_options.focal = 700;
  scene_options.camera_distance = 6.0;
  scene_options.camera_height = 1.5;
  scene_options.scene_radius = 1.5;
  scene_options.pixel_noise_stddev = 0.3;
  scene_options.seed = 5;
  SceneRun run;
  run.scene = SynthesizeScene(scene_options);
  MapperInput input = InputFromScene(run.scene, scene_options.focal);
  FilterMatches(run.scene, &input, [](int i, int j, int point) {
    const double facing = std::fmod(point * 137.5, 360.0);
    auto sees = [&](int k) { return std::abs(std::remainder(45.0 * k - facing, 360.0)) <= 50; };
    return sees(i) && sees(j);
  });
  IncrementalMapperOptions options;
  options.relative_registration = relative_registration;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  return run;
}

TEST(ReconstructIncrementally, WideGapsNeedRelativePoses) {
  const SceneRun without = ReconstructWideRing(false);
  ASSERT_FALSE(without.models.empty());
  EXPECT_LE(without.models.front().images.size(), 3u) << "PnP alone stops at the first gap";

  const SceneRun with = ReconstructWideRing(true);
  ASSERT_EQ(with.models.size(), 1u);
  EXPECT_EQ(with.models.front().images.size(), 8u);
  int relative = 0;
  for (const std::string& line : with.summary.log)
    relative += line.find("by relative pose") != std::string::npos;
  EXPECT_GE(relative, 5);
  EXPECT_EQ(with.summary.num_relative_registrations, relative);
  EXPECT_EQ(without.summary.num_relative_registrations, 0);
  const Errors errors = Compare(with.models.front(), with.scene);
  EXPECT_LT(errors.max_rotation_deg, 0.5);
  EXPECT_LT(errors.max_center, 0.01 * SyntheticSceneOptions().camera_distance);
}

// Few-feature photos: a ring of 8 photos of 40 points, so every pair has at most 40 matches,
// fewer than an initial pair needs (50). With nothing better, a weak initial pair (most
// matches on one essential matrix, a wide angle) starts the model, and the rest register by
// PnP from the same few points.
SceneRun ReconstructFewMatches(int weak_initial_inliers, SyntheticCameraLayout layout) {
  SyntheticSceneOptions scene_options;
  scene_options.layout = layout;
  scene_options.num_cameras = 8;
  scene_options.num_points = 40;
  scene_options.pixel_noise_stddev = 0.5;
  scene_options.seed = 11;
  SceneRun run;
  run.scene = SynthesizeScene(scene_options);
  const MapperInput input = InputFromScene(run.scene, scene_options.focal);
  IncrementalMapperOptions options;
  options.weak_initial_inliers = weak_initial_inliers;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  return run;
}

TEST(ReconstructIncrementally, WeakInitialPairWhenNothingBetterExists) {
  const SceneRun without = ReconstructFewMatches(0, SyntheticCameraLayout::kRing);
  EXPECT_TRUE(without.models.empty()) << "no pair has the 50 matches of the usual bar";

  const SceneRun with = ReconstructFewMatches(20, SyntheticCameraLayout::kRing);
  ASSERT_EQ(with.models.size(), 1u);
  EXPECT_EQ(with.models.front().images.size(), 8u);
  int weak = 0;
  for (const std::string& line : with.summary.log) weak += line.rfind("weak initial pair", 0) == 0;
  EXPECT_EQ(weak, 1);
  const Errors errors = Compare(with.models.front(), with.scene);
  EXPECT_LT(errors.max_rotation_deg, 1.0);
  EXPECT_LT(errors.max_center, 0.02 * SyntheticSceneOptions().camera_distance);
}

TEST(ReconstructIncrementally, WeakInitialPairStillNeedsParallax) {
  const SceneRun run = ReconstructFewMatches(20, SyntheticCameraLayout::kPureRotation);
  EXPECT_TRUE(run.models.empty()) << "no parallax: not even a weak initial pair";
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

// The temple-like ring with a heavy tail: one keypoint in `tail_every` is moved 3-3.9 px (a
// blob centred differently in that photo, as across a wide baseline), below the 4 px bar of
// the growing model. Points are seen from 2-3 photos (within 35 deg), the focal is known.
struct TailRun {
  SceneRun run;
  std::set<std::pair<int, int>> moved;  // (image, keypoint)
  // Observations of the largest model whose keypoint was moved, and the others.
  int moved_observations = 0;
  int clean_observations = 0;
};

TailRun ReconstructRingWithATail(int tail_every, double final_outlier_multiple) {
  TailRun tail;
  SceneRun& run = tail.run;
  run.scene = SynthesizeScene(TempleLikeRing(16, 1000, 5));
  MapperInput input = InputFromScene(run.scene, /*focal_guess=*/1536);
  FilterMatches(run.scene, &input, [](int i, int j, int point) {
    const double facing = std::fmod(point * 137.5, 360.0);
    auto sees = [&](int k) { return std::abs(std::remainder(22.5 * k - facing, 360.0)) <= 35; };
    return sees(i) && sees(j);
  });
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (auto& [id, image] : input.images) {
    for (int kp = 0; kp < static_cast<int>(image.keypoints.size()); ++kp) {
      const double angle = 2 * M_PI * unit(rng);
      const double length = 3.0 + 0.9 * unit(rng);
      if (tail_every > 0 && unit(rng) * tail_every < 1.0) {
        image.keypoints[kp] += length * Eigen::Vector2d(std::cos(angle), std::sin(angle));
        tail.moved.insert({id, kp});
      }
    }
  }
  IncrementalMapperOptions options;
  options.final_outlier_multiple = final_outlier_multiple;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  if (!run.models.empty()) {
    for (const auto& [id, point] : run.models.front().points) {
      for (const Observation& o : point.observations) {
        (tail.moved.count({o.image_id, o.keypoint}) ? tail.moved_observations
                                                    : tail.clean_observations)++;
      }
    }
  }
  return tail;
}

std::string FinalFilterLine(const MapperSummary& summary) {
  for (const std::string& line : summary.log) {
    if (line.find("final outlier filter") != std::string::npos) return line;
  }
  return "";
}

TEST(ReconstructIncrementally, FinalOutlierFilterRemovesTheTail) {
  const TailRun kept = ReconstructRingWithATail(/*tail_every=*/8, /*multiple=*/0.0);
  const TailRun filtered = ReconstructRingWithATail(/*tail_every=*/8, /*multiple=*/6.0);
  ASSERT_EQ(kept.run.models.size(), 1u);
  ASSERT_EQ(filtered.run.models.size(), 1u);
  EXPECT_EQ(filtered.run.models.front().images.size(), 16u);
  const double before = RelativeRotationErrorDeg(kept.run.models.front(), kept.run.scene);
  const double after = RelativeRotationErrorDeg(filtered.run.models.front(), filtered.run.scene);
  const std::string line = FinalFilterLine(filtered.run.summary);
  std::cout << "moved observations kept " << kept.moved_observations << " -> "
            << filtered.moved_observations << ", clean " << kept.clean_observations << " -> "
            << filtered.clean_observations << "; relative rotations " << before << " -> " << after
            << " deg; " << line << "\n";
  EXPECT_EQ(FinalFilterLine(kept.run.summary), "");
  EXPECT_NE(line, "");
  // The 4 px bar keeps all of the tail. The final filter takes what reprojects beyond 6
  // medians (a moved keypoint of a point seen twice shares its error with the other photo,
  // so about a quarter goes here), and the clean observations stay.
  EXPECT_GT(kept.moved_observations, 300);
  EXPECT_LT(filtered.moved_observations, 0.8 * kept.moved_observations);
  EXPECT_GT(filtered.clean_observations, 0.995 * kept.clean_observations);
  EXPECT_LT(after, 1.05 * before);
}

TEST(ReconstructIncrementally, FinalOutlierFilterLeavesGaussianNoiseAlone) {
  const TailRun tail = ReconstructRingWithATail(/*tail_every=*/0, /*multiple=*/6.0);
  ASSERT_EQ(tail.run.models.size(), 1u);
  const std::string line = FinalFilterLine(tail.run.summary);
  std::cout << line << "\n";
  // 0.3 px noise: a bar of about 1.5 px, which Gaussian noise does not reach.
  EXPECT_NE(line.find(": 0 of "), std::string::npos) << line;
}

// A photo whose tracks put it in a false place while one of its verified pairs says otherwise:
// on a ring of 10 photos, photo 5's matches with photo 6 are the projections of the points
// photos 6 and 7 see through a false pose (photo 5's, orbited 50 deg about the scene towards
// photo 6), and its matches with photo 4 (every fourth point they share) are true. PnP places
// it by the larger, self-consistent false set; the model then explains few of the pair with
// photo 4, whose own relative pose explains them all, 50 deg away: the check removes photo 5.
SceneRun ReconstructRingWithAMisplacedPhoto(double contradiction_min_rotation_deg,
                                            double orbit_deg = 50.0,
                                            double contradiction_clear_rotation_deg = 5.0) {
  SyntheticSceneOptions scene_options = NoisyRingOptions();
  scene_options.k1 = 0.0;
  scene_options.outlier_fraction = 0.0;
  scene_options.seed = 41;
  SceneRun run;
  run.scene = SynthesizeScene(scene_options);
  const SyntheticScene& scene = run.scene;
  constexpr int kMisplaced = 5;
  MapperInput input = InputFromScene(scene, scene_options.focal);
  // The false pose: photo 5 orbited `orbit_deg` about the vertical through the origin, the way
  // that brings it nearer photo 6.
  const Rigid3d& truth = scene.images[kMisplaced].cam_from_world;
  Rigid3d misplaced;
  double nearest = std::numeric_limits<double>::infinity();
  for (const double sign : {-1.0, 1.0}) {
    const Rigid3d orbit(Eigen::Quaterniond(Eigen::AngleAxisd(sign * orbit_deg * M_PI / 180.0,
                                                             Eigen::Vector3d::UnitZ())),
                        Eigen::Vector3d::Zero());
    const Rigid3d candidate = truth * orbit;
    const double distance =
        (candidate.CenterInWorld() - scene.images[kMisplaced + 1].cam_from_world.CenterInWorld())
            .norm();
    if (distance < nearest) {
      nearest = distance;
      misplaced = candidate;
    }
  }
  // Photo 5's keypoints: its true observations, then the false ones.
  MapperImage& image = input.images.at(kMisplaced);
  const Camera& camera = scene.images[kMisplaced].camera;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, scene_options.pixel_noise_stddev);
  std::map<int, int> observation_of_point;  // In photo 7.
  for (int k = 0; k < static_cast<int>(scene.images[kMisplaced + 2].observations.size()); ++k) {
    const SyntheticObservation& o = scene.images[kMisplaced + 2].observations[k];
    if (!o.is_outlier) observation_of_point[o.point_index] = k;
  }
  std::vector<FeatureMatch> false_matches;  // Photo 5 (false keypoints) with photo 6.
  for (int k = 0; k < static_cast<int>(scene.images[kMisplaced + 1].observations.size()); ++k) {
    const SyntheticObservation& o = scene.images[kMisplaced + 1].observations[k];
    if (o.is_outlier || !observation_of_point.count(o.point_index)) continue;
    const Eigen::Vector3d in_camera = misplaced * scene.points3D[o.point_index];
    if (in_camera.z() <= 0) continue;
    const auto pixel = camera.ImgFromCam(in_camera);
    if (!pixel || pixel->x() < 0 || pixel->y() < 0 || pixel->x() > scene_options.width - 1 ||
        pixel->y() > scene_options.height - 1) {
      continue;
    }
    image.keypoints.push_back(*pixel + Eigen::Vector2d(noise(rng), noise(rng)));
    false_matches.push_back({static_cast<int>(image.keypoints.size()) - 1, k});
  }
  std::vector<MapperPair> pairs;
  std::vector<PairMatches> pair_matches;
  for (MapperPair& pair : input.pairs) {
    if (pair.image1 == kMisplaced || pair.image2 == kMisplaced) {
      if (pair.image1 == kMisplaced - 1) {
        std::vector<FeatureMatch> kept;
        for (std::size_t m = 0; m < pair.matches.size(); m += 4) kept.push_back(pair.matches[m]);
        pair.matches = kept;
      } else if (pair.image2 == kMisplaced + 1) {
        pair.matches = false_matches;
      } else {
        continue;
      }
      pair.num_inliers_F = static_cast<int>(pair.matches.size());
    }
    pair_matches.push_back({pair.image1, pair.image2, pair.matches});
    pairs.push_back(std::move(pair));
  }
  input.pairs = std::move(pairs);
  input.tracks = BuildTracks(pair_matches);
  IncrementalMapperOptions options;
  options.contradiction_min_rotation_deg = contradiction_min_rotation_deg;
  options.contradiction_clear_rotation_deg = contradiction_clear_rotation_deg;
  Progress progress;
  run.models = ReconstructIncrementally(input, options, progress, CancelToken(), &run.summary);
  return run;
}

// The run kept photo 5 in its model, misplaced: the model's worst rotation over `min_deg`.
void ExpectPhotoFiveMisplaced(const SceneRun& run, const char* label, double min_deg) {
  ASSERT_FALSE(run.models.empty());
  ASSERT_TRUE(run.models[0].images.count(5)) << "the scene places photo 5 wrongly";
  const Errors misplaced = Compare(run.models[0], run.scene);
  std::cout << label << ": " << run.models[0].images.size() << " photos, max rotation "
            << misplaced.max_rotation_deg << " deg\n";
  EXPECT_GT(misplaced.max_rotation_deg, min_deg);
}

// The check removed photo 5, and only it: the other 9 photos within 0.3 deg.
void ExpectPhotoFiveRemoved(const SceneRun& run, const char* label) {
  ASSERT_FALSE(run.models.empty());
  EXPECT_EQ(run.summary.num_contradicted, 1);
  EXPECT_FALSE(run.models[0].images.count(5));
  EXPECT_EQ(run.models[0].images.size(), 9u);
  const Errors errors = Compare(run.models[0], run.scene);
  std::cout << label << ": " << run.models[0].images.size() << " photos, max rotation "
            << errors.max_rotation_deg << " deg\n";
  EXPECT_LT(errors.max_rotation_deg, 0.3);
}

TEST(ReconstructIncrementally, APhotoWhosePoseContradictsAVerifiedPairIsRemoved) {
  const SceneRun unchecked = ReconstructRingWithAMisplacedPhoto(/*off=*/0.0);
  ASSERT_NO_FATAL_FAILURE(ExpectPhotoFiveMisplaced(unchecked, "unchecked", 20.0));

  const SceneRun checked = ReconstructRingWithAMisplacedPhoto(15.0);
  ASSERT_NO_FATAL_FAILURE(ExpectPhotoFiveRemoved(checked, "checked"));
  bool logged = false;
  for (const std::string& line : checked.summary.log) {
    logged = logged || line.starts_with("removed view5 from the model");
  }
  EXPECT_TRUE(logged);
}

// A photo placed 10 deg off: under the 15 deg bar, but its pair with photo 4, whose own
// relative pose explains every match while the model explains few, is a clear contradiction
// at 5 deg (contradiction_clear_rotation_deg).
TEST(ReconstructIncrementally, AClearContradictionRemovesAPhotoPlacedAFewDegreesOff) {
  const SceneRun lenient = ReconstructRingWithAMisplacedPhoto(15.0, /*orbit_deg=*/10.0,
                                                              /*clear_rotation_deg=*/15.0);
  ASSERT_NO_FATAL_FAILURE(ExpectPhotoFiveMisplaced(lenient, "15 deg bar only", 5.0));
  EXPECT_EQ(lenient.summary.num_contradicted, 0);

  const SceneRun checked = ReconstructRingWithAMisplacedPhoto(15.0, /*orbit_deg=*/10.0);
  ASSERT_NO_FATAL_FAILURE(ExpectPhotoFiveRemoved(checked, "with the clear bar"));
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
               CanceledError);
}

}  // namespace
}  // namespace reconduit
