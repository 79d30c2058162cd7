#include "core/mvs/view_selection.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>

namespace reconduit {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

// A camera `distance` from the origin, `azimuth_deg` around the z axis from +x, 30 deg above
// the horizon, looking at the origin.
Eigen::Vector3d CenterAt(double azimuth_deg, double distance) {
  const double a = azimuth_deg * kRadPerDeg, e = 30.0 * kRadPerDeg;
  return distance *
         Eigen::Vector3d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
}

// Points on a 1 m square grid patch of the plane z = 0 around the origin, seen by every
// camera (all look at the origin with a wide field of view); each camera observes every point
// in front of it at its exact projection (and for which `sees`, when given, is true).
Reconstruction MakeModel(const std::vector<Eigen::Vector3d>& centers,
                         int grid = 15,
                         const std::function<bool(int, const Eigen::Vector3d&)>& sees = {}) {
  Reconstruction model;
  model.cameras[0] = Camera::FromFocal(1000, 1000, 800.0);
  for (std::size_t i = 0; i < centers.size(); ++i) {
    RegisteredImage& image = model.images[static_cast<int>(i)];
    image.image_id = static_cast<int>(i);
    image.camera_id = 0;
    image.cam_from_world =
        Rigid3d::LookAt(centers[i], Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
  }
  for (int gy = 0; gy < grid; ++gy) {
    for (int gx = 0; gx < grid; ++gx) {
      const Eigen::Vector3d x(-0.5 + gx / (grid - 1.0), -0.5 + gy / (grid - 1.0), 0.0);
      std::vector<Observation> observations;
      for (auto& [id, image] : model.images) {
        const auto pixel = model.cameras[0].ImgFromCam(image.cam_from_world * x);
        if (!pixel || !model.cameras[0].InImage(*pixel) || (sees && !sees(id, x))) continue;
        image.keypoints.push_back(*pixel);
        image.point_for_keypoint.push_back(kInvalidId);
        observations.push_back({id, static_cast<int>(image.keypoints.size()) - 1});
      }
      if (observations.size() >= 2) model.AddPoint(x, observations);
    }
  }
  return model;
}

std::vector<int> Ids(const std::vector<ViewNeighbor>& neighbors) {
  std::vector<int> ids;
  for (const ViewNeighbor& n : neighbors) ids.push_back(n.image_id);
  return ids;
}

TEST(ViewSelection, PrefersUsefulAnglesAndDropsTooSmallOrTooLargeOnes) {
  // 0: the reference; 1: 0.5 deg away (too little parallax); 2: 4 deg; 3: 14 deg; 4: 100 deg
  // (beyond the 60 deg limit); 5: the same centre as 0 (a pure rotation: no parallax).
  const Reconstruction model = MakeModel({CenterAt(0, 5), CenterAt(0.5, 5), CenterAt(4, 5),
                                          CenterAt(14, 5), CenterAt(100, 5), CenterAt(0, 5)});
  const auto views = SelectViews(model);
  ASSERT_EQ(views.size(), 6u);
  EXPECT_EQ(Ids(views.at(0)), (std::vector<int>{3, 2}));
  const ViewNeighbor& best = views.at(0).front();
  EXPECT_EQ(best.shared_points, 225);
  // The angle at the points: about 14 deg x cos(30 deg) of elevation.
  EXPECT_NEAR(best.median_angle_deg, 12.1, 0.6);
  EXPECT_NEAR(best.median_scale_ratio, 1.0, 0.02);
  // Fully weighted at and above 10 deg and at equal resolution: the score is about the number
  // of points (the grid's corners are a little nearer to one camera than to the other).
  EXPECT_NEAR(best.score, 225.0, 2.5);
  // At ~3.5 deg each point weighs about (3.5 / 10)^2.
  EXPECT_NEAR(views.at(0)[1].score / 225.0, std::pow(views.at(0)[1].median_angle_deg / 10.0, 2),
              0.02);
}

TEST(ViewSelection, PenalisesACoarserNeighbour) {
  // 1 and 2 see the points from about the same angle, 2 from four times as far (its pixels
  // cover four times the surface).
  const Reconstruction model = MakeModel({CenterAt(0, 5), CenterAt(20, 5), CenterAt(-20, 20)});
  const auto views = SelectViews(model);
  ASSERT_EQ(Ids(views.at(0)), (std::vector<int>{1, 2}));
  const ViewNeighbor& coarse = views.at(0)[1];
  EXPECT_NEAR(coarse.median_scale_ratio, 4.0, 0.3);
  EXPECT_NEAR(coarse.score / views.at(0)[0].score, 1.0 / coarse.median_scale_ratio, 0.1);
  // Seen from the coarse photo, the reference is four times finer: a mild penalty (2 x 1/4).
  ASSERT_FALSE(views.at(2).empty());
  EXPECT_NEAR(views.at(2).front().median_scale_ratio, 0.25, 0.03);
}

TEST(ViewSelection, NeedsSharedPointsAndHonoursTheLimits) {
  // Two groups far apart that share nothing: cameras around x = 0 and a camera looking at a
  // region the grid does not cover (it sees no point at all).
  std::vector<Eigen::Vector3d> centers;
  for (int k = 0; k < 10; ++k) centers.push_back(CenterAt(15.0 * k, 5));
  Reconstruction model = MakeModel(centers);
  const int lonely = 10;
  RegisteredImage& image = model.images[lonely];
  image.image_id = lonely;
  image.camera_id = 0;
  image.cam_from_world = Rigid3d::LookAt(Eigen::Vector3d(50, 50, 3), Eigen::Vector3d(60, 60, 0),
                                         Eigen::Vector3d::UnitZ());

  ViewSelectionOptions options;
  options.max_neighbors = 3;
  const auto views = SelectViews(model, options);
  EXPECT_TRUE(views.at(lonely).empty());
  for (int k = 0; k < 10; ++k) {
    EXPECT_LE(views.at(k).size(), 3u) << k;
    for (const ViewNeighbor& n : views.at(k)) EXPECT_NE(n.image_id, lonely);
  }
  // The nearest cameras on the ring (15 and 30 deg away) beat the far ones.
  EXPECT_TRUE(Ids(views.at(5))[0] == 4 || Ids(views.at(5))[0] == 6);

  options.min_shared_points = 226;  // More than the 225 points there are.
  for (const auto& [id, neighbors] : SelectViews(model, options)) EXPECT_TRUE(neighbors.empty());

  options = {};
  options.min_relative_score = 1.0;  // Only neighbours as good as the best one.
  for (const auto& [id, neighbors] : SelectViews(model, options)) {
    for (const ViewNeighbor& n : neighbors) EXPECT_EQ(n.score, neighbors.front().score);
  }
}

TEST(ViewSelection, ChoosesSourcesThatCoverTheReference) {
  // 1 and 2 see the left half of the reference's points from wide angles (the best scores);
  // 3 sees the right half, which no other photo sees, from a small angle (4 deg: a low score).
  const auto sees = [](int camera, const Eigen::Vector3d& x) {
    return camera == 0 || (camera == 3 ? x.x() >= 0.0 : x.x() < 0.0);
  };
  const Reconstruction model =
      MakeModel({CenterAt(0, 5), CenterAt(20, 5), CenterAt(-20, 5), CenterAt(4, 5)}, 15, sees);
  ViewSelectionOptions options;
  options.coverage_sources = 0;  // By score alone: the two that see the same half.
  const auto by_score = SelectViews(model, options);
  ASSERT_EQ(by_score.at(0).size(), 3u);
  EXPECT_EQ(by_score.at(0)[2].image_id, 3);
  EXPECT_LT(by_score.at(0)[2].score, 0.3 * by_score.at(0)[1].score);

  options.coverage_sources = 2;  // The best-scored, then the one that sees the rest.
  const auto for_coverage = SelectViews(model, options);
  ASSERT_EQ(for_coverage.at(0).size(), 3u);
  EXPECT_EQ(for_coverage.at(0)[0].image_id, by_score.at(0)[0].image_id);
  EXPECT_EQ(for_coverage.at(0)[1].image_id, 3);
  EXPECT_EQ(for_coverage.at(0)[2].image_id, by_score.at(0)[1].image_id);
  // The neighbours themselves and their figures are those of the score order.
  EXPECT_EQ(for_coverage.at(0)[1].score, by_score.at(0)[2].score);

  // When every neighbour sees everything, coverage is a tie broken by the weights: the order
  // by score stays (the ring of PrefersUsefulAngles...: 14 deg before 4 deg).
  const Reconstruction all = MakeModel({CenterAt(0, 5), CenterAt(4, 5), CenterAt(14, 5)});
  EXPECT_EQ(Ids(SelectViews(all).at(0)), (std::vector<int>{2, 1}));
}

TEST(ViewSelection, ChecksItsOptions) {
  std::string error;
  ViewSelectionOptions options;
  EXPECT_TRUE(options.Check(&error)) << error;
  options.max_neighbors = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("max_neighbors"), std::string::npos);
  options = {};
  options.ideal_triangulation_angle_deg = 0.5;  // Below min.
  EXPECT_FALSE(options.Check(&error));
  options = {};
  options.min_relative_score = 2.0;
  EXPECT_FALSE(options.Check(&error));
  options = {};
  options.coverage_sources = 33;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("coverage_sources"), std::string::npos);
  EXPECT_THROW(SelectViews(Reconstruction(), options), CheckError);
}

}  // namespace
}  // namespace reconduit
