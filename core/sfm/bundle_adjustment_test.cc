#include "core/sfm/bundle_adjustment.h"

#include "core/scene/synthetic.h"
#include "core/sfm/reprojection_error.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace reconduit {
namespace {

// A synthetic scene turned into a Reconstruction, with the ground truth kept aside.
struct TestScene {
  Reconstruction truth;  // Exact poses, points and intrinsics; observations as synthesised.
  SyntheticScene synthetic;
};

// Azimuth in degrees of a world point about the vertical (z) axis.
double AzimuthDeg(const Eigen::Vector3d& p) { return std::atan2(p.y(), p.x()) * 180.0 / M_PI; }

// Every observation becomes a keypoint of its image and an observation of the point it was
// generated from (outliers included: they are wrong matches of that point). Points seen
// fewer than twice are dropped. Point ids follow the synthetic point indices.
//
// The generator has no occlusion: every point is seen by every camera that frames it, which
// makes all images covisible. With `visibility_half_angle_deg` > 0, an observation is kept
// only when the camera's azimuth is within that angle of the point's own azimuth (a point on
// the -y side is seen from the -y side), which gives short tracks and sparse covisibility as
// in real photo sets.
TestScene MakeScene(const SyntheticSceneOptions& options, double visibility_half_angle_deg = 0) {
  TestScene scene;
  scene.synthetic = SynthesizeScene(options);
  Reconstruction& rec = scene.truth;
  std::vector<std::vector<Observation>> observations(scene.synthetic.points3D.size());
  for (std::size_t i = 0; i < scene.synthetic.images.size(); ++i) {
    const SyntheticImage& synthetic_image = scene.synthetic.images[i];
    rec.cameras[synthetic_image.camera_id] = synthetic_image.camera;
    RegisteredImage& image = rec.images[static_cast<int>(i)];
    image.image_id = static_cast<int>(i);
    image.camera_id = synthetic_image.camera_id;
    image.name = "image" + std::to_string(i);
    image.cam_from_world = synthetic_image.cam_from_world;
    const double camera_azimuth = AzimuthDeg(synthetic_image.cam_from_world.CenterInWorld());
    for (const SyntheticObservation& o : synthetic_image.observations) {
      if (visibility_half_angle_deg > 0.0) {
        const double difference = std::remainder(
            camera_azimuth - AzimuthDeg(scene.synthetic.points3D[o.source_point]), 360.0);
        if (std::abs(difference) > visibility_half_angle_deg) continue;
      }
      observations[o.source_point].push_back(
          {static_cast<int>(i), static_cast<int>(image.keypoints.size())});
      image.keypoints.push_back(o.pixel);
    }
    image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
  }
  for (std::size_t p = 0; p < observations.size(); ++p) {
    if (observations[p].size() < 2) continue;
    rec.AddPoint(scene.synthetic.points3D[p], observations[p]);
  }
  return scene;
}

SyntheticSceneOptions SmallSceneOptions() {
  SyntheticSceneOptions options;
  options.num_cameras = 12;
  options.num_points = 600;
  options.layout = SyntheticCameraLayout::kRing;
  options.focal = 500.0;
  options.k1 = -0.08;
  options.k2 = 0.01;
  options.seed = 7;
  return options;
}

Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
}

// Rotates by `angle_deg` about a random axis and moves the translation by a random vector of
// length `translation_fraction` |t|.
Rigid3d PerturbPose(const Rigid3d& pose,
                    double angle_deg,
                    double translation_fraction,
                    std::mt19937_64& rng) {
  const Eigen::Quaterniond delta(Eigen::AngleAxisd(angle_deg * M_PI / 180.0, RandomUnit(rng)));
  return Rigid3d(
      delta * pose.rotation,
      pose.translation + translation_fraction * pose.translation.norm() * RandomUnit(rng));
}

// The translation coordinate of image 1 that BundleAdjust's automatic choice would hold (the
// largest coordinate of image 0's centre in image 1's frame), computed from the truth.
int ScaleIndex(const Reconstruction& truth) {
  const Eigen::Vector3d d =
      truth.images.at(1).cam_from_world * truth.images.at(0).cam_from_world.CenterInWorld();
  int index = 0;
  d.cwiseAbs().maxCoeff(&index);
  return index;
}

// Perturbs every pose except image 0's (the gauge), all points and the intrinsics. Image 1's
// translation coordinate `scale_index` keeps its true value, so that with image 0 constant
// and that coordinate held, the optimum is the truth itself, not a similar copy of it.
Reconstruction Perturb(const Reconstruction& truth,
                       double angle_deg,
                       double translation_fraction,
                       double point_sigma,
                       double focal_factor,
                       double k1_offset,
                       std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Reconstruction rec = truth;
  const int scale_index = ScaleIndex(truth);
  for (auto& [id, image] : rec.images) {
    if (id == 0) continue;
    const double t_fixed = image.cam_from_world.translation[scale_index];
    image.cam_from_world = PerturbPose(image.cam_from_world, angle_deg, translation_fraction, rng);
    if (id == 1) image.cam_from_world.translation[scale_index] = t_fixed;
  }
  std::normal_distribution<double> normal(0.0, point_sigma);
  for (auto& [id, point] : rec.points) {
    point.xyz_in_world += Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  }
  for (auto& [id, camera] : rec.cameras) {
    camera.focal *= focal_factor;
    camera.k1 += k1_offset;
  }
  return rec;
}

BundleAdjustmentOptions GaugeFixedOptions(const Reconstruction& truth) {
  BundleAdjustmentOptions options;
  options.constant_pose_image_ids = {0};
  options.scale_fixing_image_id = 1;
  options.scale_fixing_translation_index = ScaleIndex(truth);
  options.num_threads = 2;
  return options;
}

struct PoseErrors {
  double max_rotation_deg = 0.0;
  double max_center = 0.0;  // World units (metres).
};

PoseErrors ComparePoses(const Reconstruction& truth, const Reconstruction& rec) {
  PoseErrors errors;
  for (const auto& [id, image] : truth.images) {
    const Rigid3d& estimate = rec.images.at(id).cam_from_world;
    errors.max_rotation_deg =
        std::max(errors.max_rotation_deg, RotationDifferenceDeg(image.cam_from_world, estimate));
    errors.max_center =
        std::max(errors.max_center,
                 (image.cam_from_world.CenterInWorld() - estimate.CenterInWorld()).norm());
  }
  return errors;
}

double MaxPointError(const Reconstruction& truth, const Reconstruction& rec) {
  double error = 0.0;
  for (const auto& [id, point] : truth.points) {
    error = std::max(error, (point.xyz_in_world - rec.points.at(id).xyz_in_world).norm());
  }
  return error;
}

// RMS reprojection error over all observations, pixels.
double Rms(const Reconstruction& rec) {
  double sum = 0.0;
  for (const auto& [id, point] : rec.points) {
    for (const Observation& o : point.observations) {
      const double e = rec.ReprojectionError(point, o);
      sum += e * e;
    }
  }
  return std::sqrt(sum / static_cast<double>(rec.NumObservations()));
}

bool SamePose(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.coeffs() == b.rotation.coeffs() && a.translation == b.translation;
}

bool SameParameters(const Reconstruction& a, const Reconstruction& b) {
  for (const auto& [id, image] : a.images) {
    if (!SamePose(image.cam_from_world, b.images.at(id).cam_from_world)) return false;
  }
  for (const auto& [id, point] : a.points) {
    if (point.xyz_in_world != b.points.at(id).xyz_in_world) return false;
  }
  for (const auto& [id, camera] : a.cameras) {
    const Camera& other = b.cameras.at(id);
    if (camera.focal != other.focal || camera.cx != other.cx || camera.cy != other.cy ||
        camera.k1 != other.k1 || camera.k2 != other.k2) {
      return false;
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

TEST(BundleAdjustmentOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(BundleAdjustmentOptions().Check(&error)) << error;
  EXPECT_TRUE(PoseRefinementOptions().Check(&error)) << error;
  const BundleAdjustmentOptions defaults;
  EXPECT_TRUE(defaults.refine_focal);
  EXPECT_FALSE(defaults.refine_principal_point);
  EXPECT_TRUE(defaults.refine_k1);
  EXPECT_TRUE(defaults.refine_k2);
}

TEST(BundleAdjustmentOptions, CheckRejectsBadOptionsWithMessage) {
  struct Case {
    std::function<void(BundleAdjustmentOptions&)> change;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](auto& o) { o.loss_scale = 0.0; }, "loss_scale"},
      {[](auto& o) { o.loss_scale = NAN; }, "loss_scale"},
      {[](auto& o) { o.max_num_iterations = 0; }, "max_num_iterations"},
      {[](auto& o) { o.function_tolerance = 0.0; }, "function_tolerance"},
      {[](auto& o) { o.gradient_tolerance = -1.0; }, "gradient_tolerance"},
      {[](auto& o) { o.parameter_tolerance = NAN; }, "parameter_tolerance"},
      {[](auto& o) { o.max_solver_time_seconds = 0.0; }, "max_solver_time_seconds"},
      {[](auto& o) {
         o.estimate_intrinsics_stddev = true;
         o.loss = BundleAdjustmentLoss::kHuber;
       },
       "estimate_intrinsics_stddev"},
      {[](auto& o) { o.max_observations_for_stddev = -1; }, "max_observations_for_stddev"},
      {[](auto& o) { o.max_poses_for_stddev = -1; }, "max_poses_for_stddev"},
      {[](auto& o) { o.max_images_dense_schur = 0; }, "max_images_dense_schur"},
      {[](auto& o) { o.max_images_sparse_schur = 10; }, "max_images_sparse_schur"},
      {[](auto& o) { o.scale_fixing_translation_index = 3; }, "scale_fixing_translation_index"},
      {[](auto& o) { o.scale_fixing_image_id = -5; }, "scale_fixing_image_id"},
      {[](auto& o) {
         o.constant_pose_image_ids = {0, 1};
         o.scale_fixing_image_id = 1;
       },
       "scale_fixing_image_id"},
  };
  for (const Case& c : cases) {
    BundleAdjustmentOptions options;
    c.change(options);
    std::string error;
    EXPECT_FALSE(options.Check(&error)) << c.field;
    EXPECT_NE(error.find(c.field), std::string::npos) << error;
    EXPECT_FALSE(options.Check(nullptr));
  }

  PoseRefinementOptions pose_options;
  pose_options.loss_scale = -1.0;
  std::string error;
  EXPECT_FALSE(pose_options.Check(&error));
  EXPECT_NE(error.find("loss_scale"), std::string::npos) << error;
}

TEST(BundleAdjust, InvalidOptionsThrow) {
  Reconstruction rec;
  BundleAdjustmentOptions options;
  options.max_num_iterations = -1;
  EXPECT_THROW(BundleAdjust(options, CancelToken(), &rec), CheckError);
  EXPECT_THROW(BundleAdjust(BundleAdjustmentOptions(), CancelToken(), nullptr), CheckError);
  options = BundleAdjustmentOptions();
  options.constant_pose_image_ids = {42};  // No such image.
  EXPECT_THROW(BundleAdjust(options, CancelToken(), &rec), CheckError);
}

TEST(BundleAdjustmentSummary, DefaultsReadNotRun) {
  const BundleAdjustmentSummary summary;
  EXPECT_FALSE(summary.success);
  EXPECT_EQ(summary.termination, "NOT_RUN");
  EXPECT_NE(summary.message.find("not run"), std::string::npos);
  EXPECT_NE(summary.BriefReport().find("NOT_RUN"), std::string::npos);
}

TEST(BundleAdjust, EmptyReconstructionReportsFailure) {
  Reconstruction rec;
  const BundleAdjustmentSummary summary =
      BundleAdjust(BundleAdjustmentOptions(), CancelToken(), &rec);
  EXPECT_FALSE(summary.success);
  EXPECT_FALSE(summary.message.empty());
  EXPECT_EQ(summary.num_observations, 0);
  EXPECT_FALSE(summary.BriefReport().empty());
}

// The functor's projection is bit-identical to Camera::ImgFromCam (same operations in the
// same order), including distortion and an off-centre principal point.
TEST(ReprojectionError, MatchesCameraImgFromCamExactly) {
  Camera camera = Camera::FromFocal(640, 480, 512.3);
  camera.cx = 321.7;
  camera.cy = 236.1;
  camera.k1 = -0.11;
  camera.k2 = 0.027;
  std::mt19937_64 rng(3);
  const Rigid3d pose = PerturbPose(Rigid3d(), 30.0, 0.0, rng) *
                       Rigid3d(Eigen::Quaterniond::Identity(), {0.1, -0.2, 0.3});
  const std::array<double, kNumIntrinsics> intrinsics = {camera.focal, camera.cx, camera.cy,
                                                         camera.k1, camera.k2};
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d point(u(rng), u(rng), 3.0 + u(rng));
    const auto expected = camera.ImgFromCam(pose * point);
    ASSERT_TRUE(expected.has_value());
    Eigen::Vector2d residual;
    ASSERT_TRUE(ProjectionResidual(pose.rotation.coeffs().data(), pose.translation.data(),
                                   point.data(), intrinsics.data(), Eigen::Vector2d::Zero(),
                                   residual.data()));
    EXPECT_EQ(residual, *expected);
  }
  // Behind the camera: no projection, evaluation fails.
  const Eigen::Vector3d behind = pose.Inverse() * Eigen::Vector3d(0.0, 0.0, -1.0);
  Eigen::Vector2d residual;
  EXPECT_FALSE(ProjectionResidual(pose.rotation.coeffs().data(), pose.translation.data(),
                                  behind.data(), intrinsics.data(), Eigen::Vector2d::Zero(),
                                  residual.data()));
}

// (a) Noise-free observations: BA recovers the exact scene from perturbed poses, points,
// focal (+5 %) and k1.
TEST(BundleAdjust, RecoversPerturbedSceneExactlyWithoutNoise) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  const Reconstruction& truth = scene.truth;
  Reconstruction rec = Perturb(truth, /*angle_deg=*/3.0, /*translation_fraction=*/0.03,
                               /*point_sigma=*/0.03, /*focal_factor=*/1.05, /*k1_offset=*/0.03,
                               /*seed=*/11);
  ASSERT_GT(Rms(rec), 10.0);  // The perturbation is far from the solution.

  const BundleAdjustmentSummary summary =
      BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_EQ(summary.num_images, 12);
  EXPECT_EQ(summary.num_variable_images, 11);
  EXPECT_EQ(summary.num_cameras, 1);
  EXPECT_EQ(summary.num_points, static_cast<int>(truth.points.size()));
  EXPECT_EQ(summary.num_observations, static_cast<int>(truth.NumObservations()));
  EXPECT_EQ(summary.linear_solver, "DENSE_SCHUR");
  EXPECT_GT(summary.initial_rms_px, 10.0);
  EXPECT_LT(summary.final_rms_px, 1e-6) << summary.BriefReport();
  EXPECT_LT(Rms(rec), 1e-6);
  EXPECT_LT(summary.final_cost, summary.initial_cost);

  const Camera& camera = rec.cameras.at(0);
  const Camera& true_camera = truth.cameras.at(0);
  EXPECT_NEAR(camera.focal / true_camera.focal, 1.0, 1e-6);
  EXPECT_NEAR(camera.k1, true_camera.k1, 1e-6);
  EXPECT_NEAR(camera.k2, true_camera.k2, 1e-6);
  // Principal point not refined by default: bit-identical.
  EXPECT_EQ(camera.cx, true_camera.cx);
  EXPECT_EQ(camera.cy, true_camera.cy);
  const PoseErrors errors = ComparePoses(truth, rec);
  EXPECT_LT(errors.max_rotation_deg, 1e-6);
  EXPECT_LT(errors.max_center, 1e-6);
  EXPECT_LT(MaxPointError(truth, rec), 1e-6);
  EXPECT_TRUE(SamePose(rec.images.at(0).cam_from_world, truth.images.at(0).cam_from_world));
  for (const auto& [id, image] : rec.images) {
    EXPECT_NEAR(image.cam_from_world.rotation.norm(), 1.0, 1e-12);
  }
}

// The same with the principal point refined too, k1 only, and the sparse solver.
TEST(BundleAdjust, RefinesPrincipalPointAndK1OnlyWithSparseSchur) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  scene_options.k2 = 0.0;
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  Reconstruction rec = Perturb(truth, 2.0, 0.02, 0.02, 0.97, -0.02, /*seed=*/12);
  rec.cameras.at(0).cx += 4.0;
  rec.cameras.at(0).cy -= 3.0;
  rec.cameras.at(0).k2 = 0.0;

  BundleAdjustmentOptions options = GaugeFixedOptions(truth);
  options.refine_principal_point = true;
  options.refine_k2 = false;
  options.linear_solver = BundleAdjustmentLinearSolver::kSparseSchur;
  const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_EQ(summary.linear_solver, "SPARSE_SCHUR");
  EXPECT_LT(summary.final_rms_px, 1e-6) << summary.BriefReport();
  const Camera& camera = rec.cameras.at(0);
  EXPECT_NEAR(camera.focal / truth.cameras.at(0).focal, 1.0, 1e-6);
  EXPECT_NEAR(camera.cx, truth.cameras.at(0).cx, 1e-5);
  EXPECT_NEAR(camera.cy, truth.cameras.at(0).cy, 1e-5);
  EXPECT_NEAR(camera.k1, truth.cameras.at(0).k1, 1e-6);
  EXPECT_EQ(camera.k2, 0.0);  // Held: bit-identical.
}

// One coordinate of the principal point held (the mapper's decision on a poorly determined
// axis): it stays bit-identical, the other is refined to the truth, the rest absorbs nothing.
TEST(BundleAdjust, HoldsOnePrincipalPointCoordinate) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  scene_options.k2 = 0.0;
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  for (const bool hold_x : {true, false}) {
    SCOPED_TRACE(hold_x ? "cx held" : "cy held");
    Reconstruction rec = Perturb(truth, 2.0, 0.02, 0.02, 0.97, -0.02, /*seed=*/12);
    rec.cameras.at(0).k2 = 0.0;
    // The held coordinate starts at the truth, the refined one 4 px off it.
    rec.cameras.at(0).cx = truth.cameras.at(0).cx + (hold_x ? 0.0 : 4.0);
    rec.cameras.at(0).cy = truth.cameras.at(0).cy + (hold_x ? -4.0 : 0.0);
    BundleAdjustmentOptions options = GaugeFixedOptions(truth);
    options.refine_principal_point = true;
    options.hold_principal_point_x = hold_x;
    options.hold_principal_point_y = !hold_x;
    options.refine_k2 = false;
    const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
    ASSERT_TRUE(summary.success) << summary.BriefReport();
    EXPECT_LT(summary.final_rms_px, 1e-6) << summary.BriefReport();
    const Camera& camera = rec.cameras.at(0);
    if (hold_x) {
      EXPECT_EQ(camera.cx, truth.cameras.at(0).cx);  // Held: bit-identical.
      EXPECT_NEAR(camera.cy, truth.cameras.at(0).cy, 1e-5);
    } else {
      EXPECT_EQ(camera.cy, truth.cameras.at(0).cy);
      EXPECT_NEAR(camera.cx, truth.cameras.at(0).cx, 1e-5);
    }
  }
}

// Every linear solver reaches the same exact solution; kAuto picks by the number of variable
// images and its thresholds.
TEST(BundleAdjust, LinearSolversAgree) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  const Reconstruction start = Perturb(scene.truth, 2.0, 0.02, 0.02, 1.03, 0.02, /*seed=*/23);
  struct Case {
    BundleAdjustmentLinearSolver solver;
    int max_images_dense_schur;
    int max_images_sparse_schur;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {BundleAdjustmentLinearSolver::kAuto, 50, 400, "DENSE_SCHUR"},
      {BundleAdjustmentLinearSolver::kAuto, 5, 400, "SPARSE_SCHUR"},
      {BundleAdjustmentLinearSolver::kAuto, 5, 10, "ITERATIVE_SCHUR"},
      {BundleAdjustmentLinearSolver::kIterativeSchur, 50, 400, "ITERATIVE_SCHUR"},
  };
  for (const Case& c : cases) {
    Reconstruction rec = start;
    BundleAdjustmentOptions options = GaugeFixedOptions(scene.truth);
    options.linear_solver = c.solver;
    options.max_images_dense_schur = c.max_images_dense_schur;
    options.max_images_sparse_schur = c.max_images_sparse_schur;
    const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
    ASSERT_TRUE(summary.success) << summary.BriefReport();
    EXPECT_EQ(summary.linear_solver, c.expected);
    EXPECT_LT(summary.final_rms_px, 1e-6) << summary.BriefReport();
    EXPECT_NEAR(rec.cameras.at(0).focal / scene.truth.cameras.at(0).focal, 1.0, 1e-6) << c.expected;
  }
}

// Fixed intrinsics stay bit-identical while the poses are refined.
TEST(BundleAdjust, ConstantCameraKeepsIntrinsics) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  Reconstruction rec = Perturb(scene.truth, 1.0, 0.01, 0.01, 1.0, 0.0, /*seed=*/13);
  BundleAdjustmentOptions options = GaugeFixedOptions(scene.truth);
  options.constant_camera_ids = {0};
  const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_LT(summary.final_rms_px, 1e-6);
  const Camera& camera = rec.cameras.at(0);
  const Camera& true_camera = scene.truth.cameras.at(0);
  EXPECT_EQ(camera.focal, true_camera.focal);
  EXPECT_EQ(camera.k1, true_camera.k1);
  EXPECT_EQ(camera.k2, true_camera.k2);
}

// (b) 0.5 px Gaussian noise: focal within 0.5 %, RMS at the noise level, and no worse than
// the truth's own RMS (BA minimises it).
TEST(BundleAdjust, NoisyObservationsRecoverFocal) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  scene_options.pixel_noise_stddev = 0.5;
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  Reconstruction rec = Perturb(truth, 2.0, 0.02, 0.02, 1.05, 0.02, /*seed=*/14);

  const BundleAdjustmentSummary summary =
      BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  std::printf("noisy BA: %s\n", summary.BriefReport().c_str());
  EXPECT_NEAR(rec.cameras.at(0).focal / truth.cameras.at(0).focal, 1.0, 0.005);
  // The 2-D error norm of N(0, 0.5² I) has RMS 0.5 sqrt(2); fitting removes a few % of it.
  const double expected_rms = 0.5 * std::sqrt(2.0);
  EXPECT_GT(summary.final_rms_px, 0.85 * expected_rms);
  EXPECT_LT(summary.final_rms_px, 1.05 * expected_rms);
  EXPECT_LE(summary.final_rms_px, Rms(truth));
  const PoseErrors errors = ComparePoses(truth, rec);
  // Image 0 alone fixes the gauge, so errors grow with the distance from it (0.1 deg is
  // 0.9 px at f = 500).
  std::printf("noisy BA: max rotation error %.4f deg, max centre error %.4f m\n",
              errors.max_rotation_deg, errors.max_center);
  EXPECT_LT(errors.max_rotation_deg, 0.3);
  EXPECT_LT(errors.max_center, 0.05);  // Metres at ~6.7 m from the scene.
}

// The intrinsics' standard deviations predicted from J^T J must match the scatter of the
// estimates over repeated noise draws (Monte Carlo), and the variance factor must find the
// true noise level when the declared keypoint standard deviations (1 px) are wrong.
// Measured with 120 draws: the principal point's prediction matches (ratio 1.0); the
// focal's falls short by 16 % at 0.05 px noise and by 44 % at 0.5 px (the focal trades off
// against depth and distortion along a curved valley that the linearisation misses): the
// bounds below accept the first, and the header documents it as a lower bound.
TEST(BundleAdjust, IntrinsicsStddevMatchesMonteCarloScatter) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();  // Exact keypoints.
  scene_options.num_points = 200;
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  BundleAdjustmentOptions options = GaugeFixedOptions(truth);
  options.estimate_intrinsics_stddev = true;
  options.refine_principal_point = true;
  constexpr int kTrials = 40;
  constexpr double kNoise = 0.05;
  std::mt19937_64 rng(31);
  std::normal_distribution<double> normal(0.0, kNoise);
  std::vector<double> focal, cx;
  double predicted_focal = 0.0, predicted_cx = 0.0, variance_factor = 0.0;
  for (int trial = 0; trial < kTrials; ++trial) {
    Reconstruction rec = truth;
    for (auto& [id, image] : rec.images) {
      for (Eigen::Vector2d& keypoint : image.keypoints) {
        keypoint += Eigen::Vector2d(normal(rng), normal(rng));
      }
    }
    const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
    ASSERT_TRUE(summary.success) << summary.BriefReport();
    ASSERT_EQ(summary.intrinsics_stddev.size(), 1u);
    const IntrinsicsStddev& stddev = summary.intrinsics_stddev.at(0);
    ASSERT_GT(stddev.focal, 0.0);
    ASSERT_GT(stddev.k2, 0.0);
    focal.push_back(rec.cameras.at(0).focal);
    cx.push_back(rec.cameras.at(0).cx);
    predicted_focal += stddev.focal / kTrials;
    predicted_cx += stddev.cx / kTrials;
    variance_factor += summary.variance_factor / kTrials;
  }
  const auto sample_stddev = [](const std::vector<double>& v) {
    double mean = 0.0, sum2 = 0.0;
    for (double x : v) mean += x / v.size();
    for (double x : v) sum2 += (x - mean) * (x - mean);
    return std::sqrt(sum2 / (v.size() - 1));
  };
  const double observed_focal = sample_stddev(focal), observed_cx = sample_stddev(cx);
  std::printf(
      "focal stddev: predicted %.4f px, observed %.4f px; cx: %.4f, %.4f; "
      "variance factor %.4f\n",
      predicted_focal, observed_focal, predicted_cx, observed_cx, variance_factor);
  EXPECT_NEAR(variance_factor, kNoise * kNoise, 0.1 * kNoise * kNoise);
  // 40 draws estimate a standard deviation to about +-11 % (1 sigma).
  EXPECT_GT(predicted_focal / observed_focal, 0.6);
  EXPECT_LT(predicted_focal / observed_focal, 1.3);
  EXPECT_GT(predicted_cx / observed_cx, 0.7);
  EXPECT_LT(predicted_cx / observed_cx, 1.4);

  // Held entries have no spread; without a fixed gauge J^T J is singular: no estimate.
  Reconstruction rec = truth;
  for (auto& [id, image] : rec.images) {
    for (Eigen::Vector2d& keypoint : image.keypoints) {
      keypoint += Eigen::Vector2d(normal(rng), normal(rng));
    }
  }
  options.refine_principal_point = false;
  BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_EQ(summary.intrinsics_stddev.size(), 1u);
  EXPECT_GT(summary.intrinsics_stddev.at(0).focal, 0.0);
  EXPECT_EQ(summary.intrinsics_stddev.at(0).cx, 0.0);
  EXPECT_EQ(summary.intrinsics_stddev.at(0).cy, 0.0);
  // Too many observations for the sparse QR: the Schur complement gives the same estimate
  // (held entries still zero); too many poses for it: no estimate.
  {
    Reconstruction again = truth;
    for (auto& [id, image] : again.images) {
      for (Eigen::Vector2d& keypoint : image.keypoints) {
        keypoint += Eigen::Vector2d(normal(rng), normal(rng));
      }
    }
    for (const bool principal_point : {false, true}) {
      BundleAdjustmentOptions schur = options;
      schur.refine_principal_point = principal_point;
      Reconstruction by_qr = again, by_schur = again;
      const BundleAdjustmentSummary qr = BundleAdjust(schur, CancelToken(), &by_qr);
      schur.max_observations_for_stddev = qr.num_observations - 1;
      const BundleAdjustmentSummary complement = BundleAdjust(schur, CancelToken(), &by_schur);
      ASSERT_EQ(qr.intrinsics_stddev.size(), 1u);
      ASSERT_EQ(complement.intrinsics_stddev.size(), 1u);
      const IntrinsicsStddev& a = qr.intrinsics_stddev.at(0);
      const IntrinsicsStddev& b = complement.intrinsics_stddev.at(0);
      EXPECT_GT(b.focal, 0.0);
      EXPECT_NEAR(b.focal, a.focal, 1e-6 * a.focal);
      EXPECT_NEAR(b.cx, a.cx, 1e-6 * a.focal);
      EXPECT_NEAR(b.cy, a.cy, 1e-6 * a.focal);
      EXPECT_NEAR(b.k1, a.k1, 1e-6 * a.k1);
      EXPECT_NEAR(b.k2, a.k2, 1e-6 * a.k2);
      EXPECT_EQ(b.cx > 0.0, principal_point);
      EXPECT_NEAR(complement.variance_factor, qr.variance_factor, 1e-6 * qr.variance_factor);
      schur.max_poses_for_stddev = static_cast<int>(truth.images.size()) - 3;
      EXPECT_TRUE(BundleAdjust(schur, CancelToken(), &by_schur).intrinsics_stddev.empty());
    }
  }
  // A robust loss would reweigh the covariance: refused.
  options.loss = BundleAdjustmentLoss::kCauchy;
  EXPECT_THROW(BundleAdjust(options, CancelToken(), &rec), CheckError);
  options.loss = BundleAdjustmentLoss::kTrivial;
  options.constant_pose_image_ids.clear();
  options.scale_fixing_image_id = kInvalidId;
  summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_TRUE(summary.success);
  EXPECT_TRUE(summary.intrinsics_stddev.empty());
  options.max_observations_for_stddev = 0;  // The Schur complement sees the free gauge too.
  summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_TRUE(summary.success);
  EXPECT_TRUE(summary.intrinsics_stddev.empty());
  options.max_observations_for_stddev = BundleAdjustmentOptions().max_observations_for_stddev;
  // Not asked for: not computed.
  summary = BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &rec);
  EXPECT_TRUE(summary.intrinsics_stddev.empty());
}

// Keypoints of two precisions (half at 0.3 px, half at 4 px, as fine and coarse SIFT scales):
// declaring each one's standard deviation (keypoint_stddevs) must recover the camera much
// better than weighing them all alike, which lets the coarse half dominate.
TEST(BundleAdjust, KeypointStddevsWeighObservations) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  Reconstruction noisy = truth;
  std::mt19937_64 rng(21);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (auto& [id, image] : noisy.images) {
    image.keypoint_stddevs.resize(image.keypoints.size());
    for (std::size_t k = 0; k < image.keypoints.size(); ++k) {
      const double stddev = k % 2 == 0 ? 0.3 : 4.0;
      image.keypoint_stddevs[k] = stddev;
      image.keypoints[k] += stddev * Eigen::Vector2d(normal(rng), normal(rng));
    }
  }
  const Reconstruction start = Perturb(noisy, 2.0, 0.02, 0.02, 1.05, 0.02, /*seed=*/15);

  Reconstruction weighted = start;
  ASSERT_TRUE(BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &weighted).success);
  Reconstruction equal = start;
  for (auto& [id, image] : equal.images) image.keypoint_stddevs.clear();
  ASSERT_TRUE(BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &equal).success);

  const double f_true = truth.cameras.at(0).focal;
  const double weighted_focal = std::abs(weighted.cameras.at(0).focal / f_true - 1.0);
  const double equal_focal = std::abs(equal.cameras.at(0).focal / f_true - 1.0);
  const PoseErrors weighted_pose = ComparePoses(truth, weighted);
  const PoseErrors equal_pose = ComparePoses(truth, equal);
  std::printf("focal error %.4f %% weighted, %.4f %% equal; rotation %.4f vs %.4f deg\n",
              100 * weighted_focal, 100 * equal_focal, weighted_pose.max_rotation_deg,
              equal_pose.max_rotation_deg);
  EXPECT_LT(weighted_focal, 0.005);  // As NoisyObservationsRecoverFocal.
  EXPECT_LT(weighted_pose.max_rotation_deg, 0.5 * equal_pose.max_rotation_deg);
  EXPECT_LT(weighted_pose.max_center, 0.5 * equal_pose.max_center);

  // One standard deviation per keypoint, or none: anything else is a caller's error.
  Reconstruction inconsistent = start;
  inconsistent.images.at(3).keypoint_stddevs.pop_back();
  EXPECT_THROW(BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &inconsistent), CheckError);
  // A standard deviation must be positive and finite: it divides the residual.
  for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    Reconstruction invalid = start;
    invalid.images.at(3).keypoint_stddevs.assign(invalid.images.at(3).keypoints.size(), bad);
    EXPECT_THROW(BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &invalid), CheckError)
        << bad;
  }
}

// (c) 5 % gross outliers: with a robust loss the poses are still recovered; with plain least
// squares they are not (which shows that the outliers matter in this test).
TEST(BundleAdjust, RobustLossWithstandsOutliers) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  scene_options.pixel_noise_stddev = 0.3;
  scene_options.outlier_fraction = 0.05;
  const TestScene scene = MakeScene(scene_options);
  const Reconstruction& truth = scene.truth;
  const Reconstruction start = Perturb(truth, 2.0, 0.02, 0.02, 1.04, 0.02, /*seed=*/15);

  PoseErrors trivial_errors;
  {
    Reconstruction rec = start;
    const BundleAdjustmentSummary summary =
        BundleAdjust(GaugeFixedOptions(truth), CancelToken(), &rec);
    ASSERT_TRUE(summary.success) << summary.BriefReport();
    trivial_errors = ComparePoses(truth, rec);
  }
  for (const BundleAdjustmentLoss loss :
       {BundleAdjustmentLoss::kHuber, BundleAdjustmentLoss::kCauchy}) {
    Reconstruction rec = start;
    BundleAdjustmentOptions options = GaugeFixedOptions(truth);
    options.loss = loss;
    options.loss_scale = 1.0;
    const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
    ASSERT_TRUE(summary.success) << summary.BriefReport();
    const PoseErrors errors = ComparePoses(truth, rec);
    SCOPED_TRACE(std::string(BundleAdjustmentLossName(loss)));
    EXPECT_LT(errors.max_rotation_deg, 0.1);
    EXPECT_LT(errors.max_center, 0.02);
    EXPECT_NEAR(rec.cameras.at(0).focal / truth.cameras.at(0).focal, 1.0, 0.005);
    EXPECT_LT(errors.max_center, 0.5 * trivial_errors.max_center);
    std::printf(
        "outliers, %s loss: max rotation error %.4f deg, max centre error %.4f m; "
        "trivial loss: %.4f deg, %.4f m\n",
        std::string(BundleAdjustmentLossName(loss)).c_str(), errors.max_rotation_deg,
        errors.max_center, trivial_errors.max_rotation_deg, trivial_errors.max_center);
  }
}

// (d) Local BA: only the variable images and the points they see move; every other pose,
// point and the intrinsics' held entries are bit-identical.
TEST(BundleAdjust, LocalAdjustmentMovesOnlyVariableImages) {
  // Each image sees part of the scene, so the local problem is a part of the whole.
  const TestScene scene = MakeScene(SmallSceneOptions(), /*visibility_half_angle_deg=*/50.0);
  const Reconstruction& truth = scene.truth;
  Reconstruction rec = truth;
  std::mt19937_64 rng(16);
  const std::set<int> variable = {4, 5};
  // Only the variable images are perturbed, so the local problem's optimum is the truth; the
  // constant images that see the local points are in the problem and must not move a bit.
  for (int id : variable) {
    rec.images.at(id).cam_from_world =
        PerturbPose(truth.images.at(id).cam_from_world, 2.0, 0.02, rng);
  }
  std::set<int> local_points;
  for (int id : variable) {
    for (int point_id : rec.images.at(id).point_for_keypoint) {
      if (point_id != kInvalidId) local_points.insert(point_id);
    }
  }
  ASSERT_GT(local_points.size(), 20u);
  ASSERT_LT(local_points.size(), rec.points.size() * 3 / 4);
  std::normal_distribution<double> normal(0.0, 0.02);
  for (int point_id : local_points) {
    rec.points.at(point_id).xyz_in_world += Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  }
  const Reconstruction before = rec;

  BundleAdjustmentOptions options;
  options.variable_pose_image_ids = {variable.begin(), variable.end()};
  options.constant_camera_ids = {0};
  const BundleAdjustmentSummary summary = BundleAdjust(options, CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_EQ(summary.num_variable_images, 2);
  EXPECT_GT(summary.num_images, 2);
  EXPECT_EQ(summary.num_points, static_cast<int>(local_points.size()));

  for (const auto& [id, image] : rec.images) {
    if (variable.contains(id)) {
      EXPECT_FALSE(SamePose(image.cam_from_world, before.images.at(id).cam_from_world)) << id;
      EXPECT_LT(RotationDifferenceDeg(image.cam_from_world, truth.images.at(id).cam_from_world),
                1e-6)
          << id;
      EXPECT_LT((image.cam_from_world.CenterInWorld() -
                 truth.images.at(id).cam_from_world.CenterInWorld())
                    .norm(),
                1e-6)
          << id;
    } else {
      EXPECT_TRUE(SamePose(image.cam_from_world, before.images.at(id).cam_from_world)) << id;
    }
  }
  for (const auto& [id, point] : rec.points) {
    if (local_points.contains(id)) {
      EXPECT_LT((point.xyz_in_world - truth.points.at(id).xyz_in_world).norm(), 1e-6) << id;
    } else {
      EXPECT_EQ(point.xyz_in_world, before.points.at(id).xyz_in_world) << id;
    }
  }
  EXPECT_EQ(rec.cameras.at(0).focal, before.cameras.at(0).focal);
}

// Points with fewer than two usable observations are skipped and left alone.
TEST(BundleAdjust, SkipsPointsWithOneObservation) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  Reconstruction rec = Perturb(scene.truth, 1.0, 0.01, 0.01, 1.0, 0.0, /*seed=*/17);
  // A lonely point: one observation of a fresh keypoint in image 2.
  RegisteredImage& image = rec.images.at(2);
  image.keypoints.push_back({100.0, 100.0});
  image.point_for_keypoint.push_back(kInvalidId);
  const int lonely = rec.AddPoint({0.5, 0.5, 0.5}, {});
  rec.AddObservation(lonely, {2, static_cast<int>(image.keypoints.size()) - 1});
  const BundleAdjustmentSummary summary =
      BundleAdjust(GaugeFixedOptions(scene.truth), CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_EQ(summary.num_skipped_points, 1);
  EXPECT_EQ(summary.num_points, static_cast<int>(scene.truth.points.size()));
  EXPECT_EQ(rec.points.at(lonely).xyz_in_world, Eigen::Vector3d(0.5, 0.5, 0.5));
  EXPECT_LT(summary.final_rms_px, 1e-6);
}

// (e) Cancellation before the solve and during it: CanceledError, reconstruction untouched.
TEST(BundleAdjust, CanceledBeforeSolveThrows) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  Reconstruction rec = Perturb(scene.truth, 2.0, 0.02, 0.02, 1.05, 0.0, /*seed=*/18);
  const Reconstruction before = rec;
  CancelToken cancel;
  cancel.RequestCancel();
  EXPECT_THROW(BundleAdjust(GaugeFixedOptions(scene.truth), cancel, &rec), CanceledError);
  EXPECT_TRUE(SameParameters(rec, before));
}

TEST(BundleAdjust, CanceledDuringSolveThrowsAndLeavesReconstructionUnchanged) {
  const TestScene scene = MakeScene(SmallSceneOptions());
  Reconstruction rec = Perturb(scene.truth, 3.0, 0.03, 0.03, 1.05, 0.03, /*seed=*/19);
  const Reconstruction before = rec;
  // The probe answers "stop" at its 4th call: the first is BundleAdjust's own check before
  // building the problem, the next ones come from the solver's iteration callback.
  CancelToken cancel;
  std::atomic<int> calls{0};
  cancel.SetProbe([&calls] { return ++calls >= 4; }, std::chrono::milliseconds(0));
  EXPECT_THROW(BundleAdjust(GaugeFixedOptions(scene.truth), cancel, &rec), CanceledError);
  EXPECT_EQ(calls.load(), 4);  // Stopped right when asked, after 2 solver iterations.
  EXPECT_TRUE(SameParameters(rec, before));

  // The same problem without cancellation needs more than 3 iterations, so the abort above
  // really happened inside the solve.
  const BundleAdjustmentSummary summary =
      BundleAdjust(GaugeFixedOptions(scene.truth), CancelToken(), &rec);
  ASSERT_TRUE(summary.success);
  EXPECT_GT(summary.num_iterations, 3);
}

// (f) Motion-only refinement recovers a perturbed pose exactly on noise-free data, and
// resists outliers with its default Cauchy loss.
TEST(RefinePose, RecoversPerturbedPose) {
  SyntheticSceneOptions scene_options = SmallSceneOptions();
  const SyntheticScene scene = SynthesizeScene(scene_options);
  const SyntheticImage& image = scene.images[3];
  std::vector<Eigen::Vector2d> points2D;
  std::vector<Eigen::Vector3d> points3D;
  for (const SyntheticObservation& o : image.observations) {
    points2D.push_back(o.pixel);
    points3D.push_back(scene.points3D[o.source_point]);
  }
  ASSERT_GT(points2D.size(), 50u);
  std::mt19937_64 rng(20);
  Rigid3d pose = PerturbPose(image.cam_from_world, 3.0, 0.03, rng);
  const BundleAdjustmentSummary summary =
      RefinePose(PoseRefinementOptions(), image.camera, points2D, points3D, &pose);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  EXPECT_EQ(summary.num_observations, static_cast<int>(points2D.size()));
  EXPECT_GT(summary.initial_rms_px, 5.0);
  EXPECT_LT(summary.final_rms_px, 1e-8);
  EXPECT_LT(RotationDifferenceDeg(pose, image.cam_from_world), 1e-8);
  EXPECT_LT((pose.CenterInWorld() - image.cam_from_world.CenterInWorld()).norm(), 1e-8);

  // 10 % of the correspondences replaced by random pixels.
  std::uniform_real_distribution<double> u(0.0, 600.0);
  for (std::size_t i = 0; i < points2D.size(); i += 10) points2D[i] = {u(rng), u(rng)};
  pose = PerturbPose(image.cam_from_world, 3.0, 0.03, rng);
  const BundleAdjustmentSummary robust =
      RefinePose(PoseRefinementOptions(), image.camera, points2D, points3D, &pose);
  ASSERT_TRUE(robust.success) << robust.BriefReport();
  EXPECT_LT(RotationDifferenceDeg(pose, image.cam_from_world), 0.01);
  EXPECT_LT((pose.CenterInWorld() - image.cam_from_world.CenterInWorld()).norm(), 1e-3);
}

TEST(RefinePose, TooFewPointsReportsFailure) {
  const Camera camera = Camera::FromFocal(640, 480, 500.0);
  Rigid3d pose;
  const Rigid3d original = pose;
  const BundleAdjustmentSummary summary =
      RefinePose(PoseRefinementOptions(), camera, {{1.0, 2.0}, {3.0, 4.0}},
                 {{0.0, 0.0, 5.0}, {1.0, 0.0, 5.0}}, &pose);
  EXPECT_FALSE(summary.success);
  EXPECT_NE(summary.message.find("at least 3"), std::string::npos) << summary.message;
  EXPECT_TRUE(SamePose(pose, original));
  EXPECT_THROW(RefinePose(PoseRefinementOptions(), camera, {{1.0, 2.0}}, {}, &pose), CheckError);
}

// Cost of a mid-sized problem: ~50 images x 5000 points (printed, not asserted).
TEST(BundleAdjust, TimingFiftyImagesFiveThousandPoints) {
  // Tracks of ~8 images, as in real photo sets. (With every point in every image -- 250 000
  // observations -- the Schur elimination dominates: ~7 s on the 2-core machine.)
  SyntheticSceneOptions scene_options;
  scene_options.num_cameras = 50;
  scene_options.num_points = 5000;
  scene_options.focal = 800.0;
  scene_options.width = 1024;
  scene_options.height = 768;
  scene_options.k1 = -0.05;
  scene_options.pixel_noise_stddev = 0.5;
  scene_options.seed = 21;
  const TestScene scene = MakeScene(scene_options, /*visibility_half_angle_deg=*/30.0);
  Reconstruction rec = Perturb(scene.truth, 1.0, 0.01, 0.01, 1.03, 0.01, /*seed=*/22);
  const BundleAdjustmentSummary summary =
      BundleAdjust(GaugeFixedOptions(scene.truth), CancelToken(), &rec);
  ASSERT_TRUE(summary.success) << summary.BriefReport();
  const double focal_error = rec.cameras.at(0).focal / scene.truth.cameras.at(0).focal - 1.0;
  std::printf("timing: %s; focal error %.3f %%\n", summary.BriefReport().c_str(),
              100.0 * focal_error);
  // 0.5 px noise with ~8-image tracks: the focal is determined to a fraction of a percent.
  EXPECT_LT(std::abs(focal_error), 0.01);
  EXPECT_LE(summary.final_rms_px, Rms(scene.truth));
}

}  // namespace
}  // namespace reconduit
