#include "core/scene/survey.h"

#include "core/scene/render.h"
#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>

namespace reconduit {
namespace {

// The height of the terrain at (x, y): the tile that contains it (tiles share their edges).
double TerrainHeight(const TexturedScene& scene, double x, double y) {
  for (const TexturedHeightField& tile : scene.height_fields) {
    if (tile.Contains(x, y)) return tile.Height(x, y);
  }
  ADD_FAILURE() << "no tile holds (" << x << ", " << y << ")";
  return NAN;
}

TEST(MakeSurvey, GridOfDownwardCamerasOverContinuousTerrain) {
  SurveyOptions options;
  options.rows = 3;
  options.cols = 4;
  const Survey survey = MakeSurvey(options);
  std::string error;
  ASSERT_TRUE(survey.scene.Check(&error)) << error;
  ASSERT_EQ(survey.cams_from_world.size(), 12u);
  for (std::size_t i = 0; i < survey.cams_from_world.size(); ++i) {
    const Rigid3d& pose = survey.cams_from_world[i];
    const Eigen::Vector3d centre = pose.CenterInWorld();
    const int r = static_cast<int>(i) / options.cols, c = static_cast<int>(i) % options.cols;
    EXPECT_NEAR(centre.x(), (c - 1.5) * options.spacing, 1e-9);
    EXPECT_NEAR(centre.y(), (r - 1.0) * options.spacing, 1e-9);
    EXPECT_NEAR(centre.z(), options.altitude, options.altitude_jitter + 1e-9);
    // The optical axis (camera +z) points down within the tilt; image up (-y) is world +y.
    const Eigen::Matrix3d world_from_cam = pose.rotation.inverse().toRotationMatrix();
    EXPECT_LE(std::acos(-world_from_cam.col(2).z()) * 180.0 / M_PI, options.max_tilt_deg + 1e-9);
    EXPECT_GT(-world_from_cam.col(1).y(), 0.9);
  }
  // The terrain is continuous across tile edges and has relief.
  double lowest = 0.0, highest = 0.0;
  for (const TexturedHeightField& tile : survey.scene.height_fields) {
    for (double t = 0.0; t <= 1.0; t += 0.05) {
      const double x = tile.min_xy.x() + t * (tile.max_xy.x() - tile.min_xy.x());
      EXPECT_NEAR(tile.Height(x, tile.min_xy.y()), 0.0, 1e-12);
      EXPECT_NEAR(tile.Height(x, tile.max_xy.y()), 0.0, 1e-12);
      EXPECT_NEAR(tile.Height(tile.min_xy.x(), tile.min_xy.y() + x - tile.min_xy.x()), 0.0, 1e-12);
    }
    const HeightFieldBounds bounds = tile.ComputeBounds();
    lowest = std::min(lowest, bounds.min_height);
    highest = std::max(highest, bounds.max_height);
    EXPECT_LT(bounds.max_slope, 0.7);  // The hills' 0.62 and the bound's margin.
  }
  EXPECT_LT(lowest, -0.2);
  EXPECT_GT(highest, 0.4);
  // Deterministic in the options; another seed, another survey.
  const Survey again = MakeSurvey(options);
  EXPECT_EQ(again.cams_from_world[5].translation, survey.cams_from_world[5].translation);
  options.seed = 1;
  EXPECT_NE(MakeSurvey(options).cams_from_world[5].translation,
            survey.cams_from_world[5].translation);
}

// Every pixel of every photo sees terrain, and neighbours overlap as a survey flight's do: the
// ground halfway between the first two photos is seen by all six of a 2 x 3 grid (up to 4.5 m
// along the row and 3 m across; a footprint is ~11 x 9 m).
TEST(MakeSurvey, PhotosSeeOnlyTerrainAndOverlapTheirNeighbours) {
  SurveyOptions options;
  options.rows = 2;
  options.cols = 3;
  options.width = 80;  // Small photos with the default field of view.
  options.height = 60;
  options.focal = 70.0;
  const Survey survey = MakeSurvey(options);
  RenderOptions render;
  render.samples_per_axis = 1;
  for (const Rigid3d& pose : survey.cams_from_world) {
    const RenderedView view = RenderScene(survey.scene, survey.camera, pose, render);
    double min_depth = 0.0, max_depth = 0.0;
    cv::minMaxLoc(view.depth, &min_depth, &max_depth);
    EXPECT_GT(min_depth, options.altitude - options.altitude_jitter - 1.0);
    EXPECT_LT(max_depth, options.altitude + options.altitude_jitter + 1.0);
  }
  const auto sees = [&](int photo, const Eigen::Vector3d& point) {
    const auto pixel = survey.camera.ImgFromCam(survey.cams_from_world[photo] * point);
    return pixel && pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() < options.width - 1 &&
           pixel->y() < options.height - 1;
  };
  const Eigen::Vector3d middle =
      0.5 * (survey.cams_from_world[0].CenterInWorld() + survey.cams_from_world[1].CenterInWorld());
  const Eigen::Vector3d ground(middle.x(), middle.y(),
                               TerrainHeight(survey.scene, middle.x(), middle.y()));
  for (int photo = 0; photo < 6; ++photo) EXPECT_TRUE(sees(photo, ground)) << photo;
}

TEST(SurveyOptions, CheckNamesTheBadField) {
  SurveyOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error));
  options.rows = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("rows"), std::string::npos);
  options = SurveyOptions();
  options.max_tilt_deg = 45.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("max_tilt_deg"), std::string::npos);
  EXPECT_THROW(MakeSurvey(options), CheckError);
}

}  // namespace
}  // namespace reconduit
