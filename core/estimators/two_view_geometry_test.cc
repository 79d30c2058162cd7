#include "core/estimators/two_view_geometry.h"

#include "core/estimators/synthetic_two_view_test_util.h"
#include "core/util/cancel.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace reconduit {
namespace {

using testing_util::DistanceUpToScale;
using testing_util::MakeTwoViewScene;
using testing_util::SceneKind;

struct PrecisionRecall {
  double precision = 0.0;
  double recall = 0.0;
};

PrecisionRecall Compare(const std::vector<char>& estimated, const std::vector<char>& truth) {
  std::size_t true_positives = 0, positives = 0, relevant = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    positives += estimated[i] ? 1 : 0;
    relevant += truth[i] ? 1 : 0;
    true_positives += estimated[i] && truth[i] ? 1 : 0;
  }
  return {positives ? double(true_positives) / positives : 0.0,
          relevant ? double(true_positives) / relevant : 0.0};
}

TEST(TwoViewGeometryOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(TwoViewGeometryOptions().Check(&error)) << error;
}

TEST(TwoViewGeometryOptions, InvalidFieldsAreNamed) {
  const auto expect_invalid = [](const TwoViewGeometryOptions& options, const std::string& field) {
    std::string error;
    EXPECT_FALSE(options.Check(&error));
    EXPECT_NE(error.find(field), std::string::npos) << error;
  };
  TwoViewGeometryOptions o;
  o.ransac.confidence = 2.0;
  expect_invalid(o, "confidence");
  o = TwoViewGeometryOptions();
  o.homography_max_error = 0.0;
  expect_invalid(o, "homography_max_error");
  o = TwoViewGeometryOptions();
  o.min_num_inliers = 6;
  expect_invalid(o, "min_num_inliers");
  o = TwoViewGeometryOptions();
  o.gric_sigma = std::numeric_limits<double>::infinity();
  expect_invalid(o, "gric_sigma");
  EXPECT_THROW(EstimateTwoViewGeometry({}, {}, o), CheckError);
}

TEST(TwoViewGeometryReport, DefaultsReadAsFailure) {
  const TwoViewGeometryReport report;
  EXPECT_FALSE(report.success);
  EXPECT_EQ(report.type, TwoViewModelType::kUndefined);
  EXPECT_EQ(report.message, "not run");
  EXPECT_TRUE(report.inlier_mask().empty());
  EXPECT_EQ(TwoViewModelTypeName(report.type), "undefined");
}

// RANSAC through the façade: 50 % outliers, 0.5 px noise.
TEST(EstimateTwoViewGeometry, RecoversFAndFlagsInliersWithHalfOutliers) {
  for (unsigned seed = 0; seed < 5; ++seed) {
    const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 200, 200, /*noise_px=*/0.5, seed);
    const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
    ASSERT_TRUE(report.success) << report.message;
    EXPECT_EQ(report.type, TwoViewModelType::kFundamental) << "seed " << seed;
    const PrecisionRecall pr = Compare(report.inlier_mask_F, scene.is_inlier);
    EXPECT_GT(pr.precision, 0.95) << "seed " << seed;
    EXPECT_GT(pr.recall, 0.95) << "seed " << seed;
    EXPECT_EQ(&report.inlier_mask(), &report.inlier_mask_F);
    EXPECT_LT(DistanceUpToScale(report.F, scene.F), 0.02) << "seed " << seed;
    EXPECT_LT(report.gric_F, report.gric_H);
    // The estimated sigma is close to the true noise.
    EXPECT_NEAR(report.gric_sigma, 0.5, 0.15);
  }
}

TEST(EstimateTwoViewGeometry, RecoversHAndFlagsInliersOnAPlaneWithHalfOutliers) {
  for (unsigned seed = 0; seed < 5; ++seed) {
    const auto scene = MakeTwoViewScene(SceneKind::kPlanar, 200, 200, /*noise_px=*/0.5, seed);
    const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
    ASSERT_TRUE(report.success) << report.message;
    EXPECT_EQ(report.type, TwoViewModelType::kHomography) << "seed " << seed;
    const PrecisionRecall pr = Compare(report.inlier_mask_H, scene.is_inlier);
    EXPECT_GT(pr.precision, 0.95) << "seed " << seed;
    EXPECT_GT(pr.recall, 0.95) << "seed " << seed;
    EXPECT_LT(DistanceUpToScale(report.H, scene.H), 0.01) << "seed " << seed;
  }
}

struct GricCase {
  SceneKind kind;
  double noise_px;
  TwoViewModelType expected;
};

class GricSelection : public ::testing::TestWithParam<GricCase> {};

TEST_P(GricSelection, PicksTheRightModel) {
  const GricCase c = GetParam();
  for (unsigned seed = 0; seed < 5; ++seed) {
    const auto scene = MakeTwoViewScene(c.kind, 300, 100, c.noise_px, 100 + seed);
    const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
    ASSERT_TRUE(report.success) << report.message;
    EXPECT_EQ(report.type, c.expected)
        << "seed " << seed << " noise " << c.noise_px << ": GRIC F " << report.gric_F << " H "
        << report.gric_H << " sigma " << report.gric_sigma << " inliers F " << report.num_inliers_F
        << " H " << report.num_inliers_H;
    // The noise estimate behind the choice is close to the truth.
    EXPECT_NEAR(report.gric_sigma, c.noise_px, 0.3 * c.noise_px) << "seed " << seed;
  }
}

INSTANTIATE_TEST_SUITE_P(
    PlanarRotationGeneral,
    GricSelection,
    ::testing::Values(GricCase{SceneKind::kPlanar, 0.5, TwoViewModelType::kHomography},
                      GricCase{SceneKind::kPlanar, 1.0, TwoViewModelType::kHomography},
                      GricCase{SceneKind::kRotation, 0.5, TwoViewModelType::kHomography},
                      GricCase{SceneKind::kRotation, 1.0, TwoViewModelType::kHomography},
                      GricCase{SceneKind::kGeneral, 0.5, TwoViewModelType::kFundamental},
                      GricCase{SceneKind::kGeneral, 1.0, TwoViewModelType::kFundamental}));

TEST(EstimateTwoViewGeometry, FixedSigmaAlsoSelectsCorrectly) {
  TwoViewGeometryOptions options;
  options.gric_sigma = 1.0;
  const auto planar = MakeTwoViewScene(SceneKind::kPlanar, 200, 50, 1.0, 7);
  const auto general = MakeTwoViewScene(SceneKind::kGeneral, 200, 50, 1.0, 7);
  const auto planar_report = EstimateTwoViewGeometry(planar.points1, planar.points2, options);
  const auto general_report = EstimateTwoViewGeometry(general.points1, general.points2, options);
  EXPECT_EQ(planar_report.gric_sigma, 1.0);
  EXPECT_EQ(planar_report.type, TwoViewModelType::kHomography);
  EXPECT_EQ(general_report.type, TwoViewModelType::kFundamental);
}

TEST(EstimateTwoViewGeometry, ReproducibleWithTheSameSeed) {
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 100, 100, 1.0, 8);
  const auto a = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
  const auto b = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.F, b.F);
  EXPECT_EQ(a.H, b.H);
  EXPECT_EQ(a.inlier_mask_F, b.inlier_mask_F);
  EXPECT_EQ(a.num_trials_F, b.num_trials_F);
  EXPECT_EQ(a.gric_F, b.gric_F);
}

TEST(EstimateTwoViewGeometry, TooFewMatchesFailWithMessage) {
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 6, 0, 0.5, 9);
  const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
  EXPECT_FALSE(report.success);
  EXPECT_EQ(report.type, TwoViewModelType::kDegenerate);
  EXPECT_NE(report.message.find("at least 7"), std::string::npos) << report.message;
  EXPECT_FALSE(EstimateTwoViewGeometry({}, {}, {}).success);
}

TEST(EstimateTwoViewGeometry, IdenticalPointsFailWithMessage) {
  const std::vector<Eigen::Vector2d> same(50, Eigen::Vector2d(320, 240));
  const auto report = EstimateTwoViewGeometry(same, same, {});
  EXPECT_FALSE(report.success);
  EXPECT_EQ(report.type, TwoViewModelType::kDegenerate);
  EXPECT_NE(report.message.find("coincident"), std::string::npos) << report.message;
}

TEST(EstimateTwoViewGeometry, CollinearPointsFailWithMessage) {
  std::vector<Eigen::Vector2d> p1, p2;
  for (int i = 0; i < 50; ++i) {
    p1.emplace_back(10.0 + 7.0 * i, 20.0 + 3.0 * i);
    p2.emplace_back(30.0 + 6.0 * i + 0.01 * i * i, 15.0 + 4.0 * i);
  }
  const auto report = EstimateTwoViewGeometry(p1, p2, {});
  EXPECT_FALSE(report.success);
  EXPECT_EQ(report.type, TwoViewModelType::kDegenerate);
  EXPECT_NE(report.message.find("collinear"), std::string::npos) << report.message;
}

TEST(EstimateTwoViewGeometry, UnrelatedMatchesAreDegenerate) {
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 0, 80, 0.0, 10);
  const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {});
  EXPECT_FALSE(report.success);
  EXPECT_EQ(report.type, TwoViewModelType::kDegenerate);
  EXPECT_NE(report.message.find("too few inliers"), std::string::npos) << report.message;
}

TEST(EstimateTwoViewGeometry, CanceledTokenStopsEstimation) {
  const auto scene = MakeTwoViewScene(SceneKind::kGeneral, 100, 100, 0.5, 11);
  CancelToken token;
  token.RequestCancel();
  const auto report = EstimateTwoViewGeometry(scene.points1, scene.points2, {}, &token);
  EXPECT_FALSE(report.success);
  EXPECT_TRUE(report.canceled);
}

TEST(EstimateTwoViewGeometry, MismatchedSizesThrow) {
  EXPECT_THROW(EstimateTwoViewGeometry({{1, 2}}, {}, {}), CheckError);
}

}  // namespace
}  // namespace reconduit
