#include "core/sfm/initial_calibration.h"

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"

#include <gtest/gtest.h>

#include <random>

namespace reconduit {
namespace {

constexpr int kWidth = 1600, kHeight = 1200;
constexpr double kFocal = 1400.0;

Eigen::Matrix3d Cross(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// The exact fundamental matrix between two photos of one camera with focal `focal`:
// F = K⁻ᵀ [t]x R K⁻¹ for the relative pose cam2_from_cam1 = (R, t).
Eigen::Matrix3d ExactFundamental(const Rigid3d& cam1_from_world,
                                 const Rigid3d& cam2_from_world,
                                 double focal) {
  const Eigen::Matrix3d r1 = cam1_from_world.rotation.toRotationMatrix();
  const Eigen::Matrix3d r2 = cam2_from_world.rotation.toRotationMatrix();
  const Eigen::Matrix3d r = r2 * r1.transpose();
  const Eigen::Vector3d t = cam2_from_world.translation - r * cam1_from_world.translation;
  const Eigen::Matrix3d k_inv = Camera::FromFocal(kWidth, kHeight, focal).K().inverse();
  const Eigen::Matrix3d f = k_inv.transpose() * Cross(t) * r * k_inv;
  return f / f.norm();
}

// A camera about 6 units from the origin looking near (not at) it: optical axes that do not
// meet, the generic case in which every pair constrains the focal.
Rigid3d GeneralCamera(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d centre = Eigen::Vector3d(u(rng), u(rng) * 0.6, -1.0).normalized() * 6.0;
  const Eigen::Vector3d target(u(rng) * 0.8, u(rng) * 0.8, u(rng) * 0.8);
  return Rigid3d::LookAt(centre, target, Eigen::Vector3d(0, -1, 0));
}

// Every pair of five photos of a camera whose true focal is `focal`, each with `inliers`.
InitialCalibrationInput CameraInput(double focal, int inliers) {
  std::mt19937 rng(7);
  std::vector<Rigid3d> poses;
  for (int i = 0; i < 5; ++i) poses.push_back(GeneralCamera(rng));
  InitialCalibrationInput input;
  input.width = kWidth;
  input.height = kHeight;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    for (std::size_t j = i + 1; j < poses.size(); ++j) {
      input.fundamentals.push_back({ExactFundamental(poses[i], poses[j], focal), inliers});
    }
  }
  return input;
}

TEST(InitialCalibrationOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(InitialCalibrationOptions().Check(&error)) << error;
}

TEST(InitialCalibrationOptions, CheckNamesTheBadField) {
  std::string error;
  InitialCalibrationOptions options;
  options.focal_disagreement = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("focal_disagreement"), std::string::npos) << error;
  options = {};
  options.default_focal_factor = -1.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("default_focal_factor"), std::string::npos) << error;
  options = {};
  options.min_self_calibration_inliers = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_self_calibration_inliers"), std::string::npos) << error;
  options = {};
  options.self_calibration.min_agreeing_pairs = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("self_calibration: min_agreeing_pairs"), std::string::npos) << error;
  EXPECT_THROW(EstimateInitialCalibration(CameraInput(kFocal, 100), options), std::exception);
}

TEST(InitialCalibration, ExifWinsWhenPresentAndAgreeing) {
  InitialCalibrationInput input = CameraInput(kFocal, 100);
  input.exif_focals = {1420.0, 1380.0, 1410.0};
  const InitialCalibration c = EstimateInitialCalibration(input);
  EXPECT_EQ(c.source, InitialFocalSource::kExif);
  EXPECT_EQ(InitialFocalSourceName(c.source), "exif");
  EXPECT_DOUBLE_EQ(c.camera.focal, 1410.0);  // The median.
  ASSERT_TRUE(c.exif_focal.has_value());
  EXPECT_DOUBLE_EQ(*c.exif_focal, 1410.0);
  ASSERT_TRUE(c.self_calibration.has_value()) << c.self_calibration_error;
  EXPECT_NEAR(c.self_calibration->focal, kFocal, 0.01 * kFocal);
  EXPECT_EQ(c.num_pairs, 10);
  EXPECT_TRUE(c.warning.empty()) << c.warning;
  EXPECT_FALSE(c.UncertainFocal());
  EXPECT_EQ(c.camera.width, kWidth);
  EXPECT_EQ(c.camera.height, kHeight);
  EXPECT_DOUBLE_EQ(c.camera.cx, (kWidth - 1) / 2.0);
  EXPECT_DOUBLE_EQ(c.camera.k1, 0.0);
}

TEST(InitialCalibration, ExifThatDisagreesWithSelfCalibrationIsUsedWithAWarning) {
  InitialCalibrationInput input = CameraInput(kFocal, 100);
  input.exif_focals = {2000.0};  // 43 % off.
  const InitialCalibration c = EstimateInitialCalibration(input);
  EXPECT_EQ(c.source, InitialFocalSource::kExif);
  EXPECT_DOUBLE_EQ(c.camera.focal, 2000.0);
  ASSERT_TRUE(c.self_calibration.has_value());
  EXPECT_EQ(c.warning, "EXIF focal length and self-calibration disagree by more than 15 %");
  EXPECT_FALSE(c.UncertainFocal());

  // Within the tolerance: no warning.
  input.exif_focals = {1.1 * kFocal};
  EXPECT_TRUE(EstimateInitialCalibration(input).warning.empty());
}

TEST(InitialCalibration, SelfCalibrationWithoutExifOrWhenExifIsNotUsed) {
  const InitialCalibration c = EstimateInitialCalibration(CameraInput(kFocal, 100));
  EXPECT_EQ(c.source, InitialFocalSource::kSelfCalibration);
  EXPECT_EQ(InitialFocalSourceName(c.source), "self_calibration");
  EXPECT_NEAR(c.camera.focal, kFocal, 0.01 * kFocal);
  EXPECT_FALSE(c.exif_focal.has_value());
  EXPECT_TRUE(c.warning.empty());
  EXPECT_FALSE(c.UncertainFocal());

  InitialCalibrationInput input = CameraInput(kFocal, 100);
  input.exif_focals = {2000.0};
  InitialCalibrationOptions options;
  options.use_exif = false;
  const InitialCalibration ignored = EstimateInitialCalibration(input, options);
  EXPECT_EQ(ignored.source, InitialFocalSource::kSelfCalibration);
  EXPECT_NEAR(ignored.camera.focal, kFocal, 0.01 * kFocal);
  ASSERT_TRUE(ignored.exif_focal.has_value());  // Recorded, not used.
  EXPECT_DOUBLE_EQ(*ignored.exif_focal, 2000.0);
  EXPECT_TRUE(ignored.warning.empty());
}

TEST(InitialCalibration, DefaultFocalIsUncertainAndWarned) {
  // No pairs at all.
  InitialCalibrationInput input;
  input.width = kWidth;
  input.height = kHeight;
  const InitialCalibration none = EstimateInitialCalibration(input);
  EXPECT_EQ(none.source, InitialFocalSource::kDefault);
  EXPECT_EQ(InitialFocalSourceName(none.source), "default");
  EXPECT_DOUBLE_EQ(none.camera.focal, 1.2 * kWidth);
  EXPECT_TRUE(none.UncertainFocal());
  EXPECT_FALSE(none.self_calibration.has_value());
  EXPECT_FALSE(none.self_calibration_error.empty());
  EXPECT_EQ(none.warning,
            "no EXIF focal length and self-calibration from photo pairs was not possible; the "
            "focal length was searched with trial reconstructions from 1.2 x the longer side");

  // Pairs with too few inliers do not take part.
  const InitialCalibration weak = EstimateInitialCalibration(CameraInput(kFocal, 49));
  EXPECT_EQ(weak.source, InitialFocalSource::kDefault);
  EXPECT_EQ(weak.num_pairs, 0);
  EXPECT_TRUE(weak.UncertainFocal());

  // EXIF present but not to be used.
  input.exif_focals = {1500.0};
  InitialCalibrationOptions options;
  options.use_exif = false;
  const InitialCalibration unused = EstimateInitialCalibration(input, options);
  EXPECT_EQ(unused.source, InitialFocalSource::kDefault);
  EXPECT_DOUBLE_EQ(unused.camera.focal, 1.2 * kWidth);
  EXPECT_TRUE(unused.UncertainFocal());
}

TEST(InitialCalibration, PortraitPhotosUseTheLongerSide) {
  InitialCalibrationInput input;
  input.width = 600;
  input.height = 900;
  EXPECT_DOUBLE_EQ(EstimateInitialCalibration(input).camera.focal, 1.2 * 900);
}

}  // namespace
}  // namespace reconduit
