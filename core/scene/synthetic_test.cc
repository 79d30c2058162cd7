#include "core/scene/synthetic.h"

#include "core/util/logging.h"

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <set>
#include <string>
#include <vector>

namespace reconduit {
namespace {

// Singular values of the centred 3-D points (one per column), largest first.
Eigen::Vector3d CenteredSingularValues(const std::vector<Eigen::Vector3d>& points) {
  Eigen::MatrixXd m(3, points.size());
  for (std::size_t i = 0; i < points.size(); ++i) m.col(i) = points[i];
  m.colwise() -= m.rowwise().mean();
  return Eigen::JacobiSVD<Eigen::MatrixXd>(m).singularValues();
}

std::vector<Eigen::Vector3d> Centers(const SyntheticScene& scene) {
  std::vector<Eigen::Vector3d> centers;
  for (const SyntheticImage& image : scene.images) {
    centers.push_back(image.cam_from_world.CenterInWorld());
  }
  return centers;
}

TEST(SyntheticSceneOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(SyntheticSceneOptions().Check(&error)) << error;
}

TEST(SyntheticSceneOptions, CheckRejectsBadOptionsWithMessage) {
  struct Case {
    std::function<void(SyntheticSceneOptions&)> change;
    std::string expected_substring;
  };
  const std::vector<Case> cases = {
      {[](auto& o) { o.num_cameras = 0; }, "num_cameras"},
      {[](auto& o) { o.scene_radius = 0.0; }, "scene_radius"},
      {[](auto& o) { o.camera_distance = 3.0; }, "camera_distance"},
      {[](auto& o) { o.camera_height = NAN; }, "camera_height"},
      {[](auto& o) { o.arc_deg = 0.0; }, "arc_deg"},
      {[](auto& o) { o.arc_deg = 361.0; }, "arc_deg"},
      {[](auto& o) { o.line_length = -1.0; }, "line_length"},
      {[](auto& o) { o.target_jitter = -0.1; }, "target_jitter"},
      {[](auto& o) { o.width = 0; }, "width and height"},
      {[](auto& o) { o.height = -1; }, "width and height"},
      {[](auto& o) { o.focal = 0.0; }, "focal"},
      {[](auto& o) { o.k2 = INFINITY; }, "k1 and k2"},
      {[](auto& o) {
         o.shared_intrinsics = false;
         o.focal_variation = 0.5;
       },
       "focal_variation"},
      {[](auto& o) {
         o.shared_intrinsics = false;
         o.principal_point_variation = -1.0;
       },
       "principal_point_variation"},
      {[](auto& o) {
         o.shared_intrinsics = false;
         o.distortion_variation = -0.1;
       },
       "distortion_variation"},
      {[](auto& o) { o.focal_variation = 0.1; }, "need shared_intrinsics = false"},
      {[](auto& o) { o.num_points = 0; }, "num_points"},
      {[](auto& o) { o.num_boxes = 0; }, "num_boxes"},
      {[](auto& o) { o.pixel_noise_stddev = -1.0; }, "pixel_noise_stddev"},
      {[](auto& o) { o.outlier_fraction = 1.5; }, "outlier_fraction"},
      {[](auto& o) { o.outlier_fraction = NAN; }, "outlier_fraction"},
  };
  for (const Case& c : cases) {
    SyntheticSceneOptions options;
    c.change(options);
    std::string error;
    EXPECT_FALSE(options.Check(&error)) << c.expected_substring;
    EXPECT_NE(error.find(c.expected_substring), std::string::npos) << error;
    EXPECT_THROW(SynthesizeScene(options), CheckError) << c.expected_substring;
  }
}

TEST(SynthesizeScene, HasRequestedSizes) {
  SyntheticSceneOptions options;
  options.num_cameras = 7;
  options.num_points = 321;
  const SyntheticScene scene = SynthesizeScene(options);
  EXPECT_EQ(scene.images.size(), 7u);
  EXPECT_EQ(scene.points3D.size(), 321u);
  for (const SyntheticImage& image : scene.images) {
    // Every camera looks at the structure, so it sees a good share of it.
    EXPECT_GT(image.observations.size(), 150u);
  }
}

TEST(SynthesizeScene, NoiseFreeObservationsReprojectExactly) {
  SyntheticSceneOptions options;
  options.k1 = -0.12;
  options.k2 = 0.03;
  options.shared_intrinsics = false;
  options.focal_variation = 0.2;
  options.principal_point_variation = 10.0;
  options.distortion_variation = 0.02;
  for (const auto layout : {SyntheticCameraLayout::kRing, SyntheticCameraLayout::kRandom}) {
    options.layout = layout;
    const SyntheticScene scene = SynthesizeScene(options);
    for (const SyntheticImage& image : scene.images) {
      ASSERT_FALSE(image.observations.empty());
      for (const SyntheticObservation& observation : image.observations) {
        EXPECT_FALSE(observation.is_outlier);
        ASSERT_GE(observation.point_index, 0);
        EXPECT_EQ(observation.point_index, observation.source_point);
        EXPECT_EQ(observation.pixel, observation.true_pixel);
        const Eigen::Vector3d point_in_cam =
            image.cam_from_world * scene.points3D[observation.point_index];
        EXPECT_GT(point_in_cam.z(), 0.0);
        const Eigen::Vector2d projection = *image.camera.ImgFromCam(point_in_cam);
        EXPECT_LT((projection - observation.pixel).norm(), 1e-9);
        EXPECT_TRUE(image.camera.InImage(observation.pixel));
      }
    }
  }
}

TEST(SynthesizeScene, ObservesExactlyThePointsInFrontAndInsideTheImage) {
  SyntheticSceneOptions options;
  options.focal = 900.0;  // Narrow, so that part of the structure is outside each view.
  options.camera_distance = 4.0;
  options.k1 = 0.05;
  options.num_points = 1000;
  const SyntheticScene scene = SynthesizeScene(options);
  int num_outside = 0;
  for (const SyntheticImage& image : scene.images) {
    std::set<int> expected, observed;
    for (int p = 0; p < static_cast<int>(scene.points3D.size()); ++p) {
      const auto pixel = image.camera.ImgFromCam(image.cam_from_world * scene.points3D[p]);
      if (pixel && image.camera.InImage(*pixel)) {
        expected.insert(p);
      } else {
        ++num_outside;
      }
    }
    int previous = -1;
    for (const SyntheticObservation& observation : image.observations) {
      EXPECT_GT(observation.source_point, previous) << "observations not sorted by point";
      previous = observation.source_point;
      observed.insert(observation.source_point);
    }
    EXPECT_EQ(observed, expected);
  }
  EXPECT_GT(num_outside, 0) << "the test needs points outside some views";
}

TEST(SynthesizeScene, DoesNotObservePointsFoldedBackByDistortion) {
  // Strong barrel distortion: r_d(r) = r (1 - 2 r²) peaks at r = sqrt(1 / 6) = 0.41 with
  // r_d = 0.27, i.e. 82 px from the centre at f = 300, well inside the 640x480 image.
  // Points beyond that radius land inside the image again, at the wrong place.
  SyntheticSceneOptions options;
  options.focal = 300.0;
  options.k1 = -2.0;
  options.scene_radius = 1.0;
  options.camera_distance = 1.8;
  options.camera_height = 0.5;
  options.num_points = 2000;
  const SyntheticScene scene = SynthesizeScene(options);
  const double fold_radius = std::sqrt(1.0 / 6.0);
  int num_folded = 0;
  for (const SyntheticImage& image : scene.images) {
    std::set<int> observed;
    for (const SyntheticObservation& observation : image.observations) {
      observed.insert(observation.source_point);
      const Eigen::Vector3d point_in_cam =
          image.cam_from_world * scene.points3D[observation.source_point];
      EXPECT_LT((point_in_cam.head<2>() / point_in_cam.z()).norm(), fold_radius);
    }
    for (int p = 0; p < static_cast<int>(scene.points3D.size()); ++p) {
      const Eigen::Vector3d point_in_cam = image.cam_from_world * scene.points3D[p];
      const auto pixel = image.camera.ImgFromCam(point_in_cam);
      if (pixel && image.camera.InImage(*pixel) &&
          (point_in_cam.head<2>() / point_in_cam.z()).norm() > fold_radius) {
        ++num_folded;
        EXPECT_EQ(observed.count(p), 0u);
      }
    }
  }
  EXPECT_GT(num_folded, 10) << "the test needs points that fold back into the image";
}

TEST(SynthesizeScene, NoiseHasRequestedStandardDeviation) {
  SyntheticSceneOptions options;
  options.num_points = 2000;
  options.pixel_noise_stddev = 1.5;
  const SyntheticScene scene = SynthesizeScene(options);
  double sum = 0.0, sum_squares = 0.0;
  int n = 0;
  for (const SyntheticImage& image : scene.images) {
    for (const SyntheticObservation& observation : image.observations) {
      const Eigen::Vector2d error = observation.pixel - observation.true_pixel;
      for (const double e : {error.x(), error.y()}) {
        sum += e;
        sum_squares += e * e;
        ++n;
      }
    }
  }
  ASSERT_GT(n, 10000);
  const double mean = sum / n;
  const double stddev = std::sqrt(sum_squares / n - mean * mean);
  // Standard error of the sample stddev is sigma / sqrt(2n) < 0.7 %.
  EXPECT_NEAR(stddev, 1.5, 0.03 * 1.5);
  EXPECT_NEAR(mean, 0.0, 0.05);
}

TEST(SynthesizeScene, OutliersHaveRequestedFractionAndAreFlagged) {
  SyntheticSceneOptions options;
  options.outlier_fraction = 0.3;
  options.pixel_noise_stddev = 0.5;
  const SyntheticScene scene = SynthesizeScene(options);
  for (const SyntheticImage& image : scene.images) {
    int num_outliers = 0;
    double outlier_error = 0.0;
    for (const SyntheticObservation& observation : image.observations) {
      EXPECT_TRUE(image.camera.InImage(observation.true_pixel));
      if (observation.is_outlier) {
        ++num_outliers;
        EXPECT_EQ(observation.point_index, -1);
        EXPECT_GE(observation.source_point, 0);
        EXPECT_TRUE(image.camera.InImage(observation.pixel));
        outlier_error += (observation.pixel - observation.true_pixel).norm();
      } else {
        EXPECT_EQ(observation.point_index, observation.source_point);
        EXPECT_LT((observation.pixel - observation.true_pixel).norm(), 0.5 * 6);
      }
    }
    EXPECT_EQ(num_outliers, std::lround(0.3 * image.observations.size()));
    // Uniform pixels are on average far (~hundreds of pixels) from the true projection.
    EXPECT_GT(outlier_error / num_outliers, 50.0);
  }
}

TEST(SynthesizeScene, AllOutliers) {
  SyntheticSceneOptions options;
  options.outlier_fraction = 1.0;
  const SyntheticScene scene = SynthesizeScene(options);
  for (const SyntheticImage& image : scene.images) {
    for (const SyntheticObservation& observation : image.observations) {
      EXPECT_TRUE(observation.is_outlier);
    }
  }
}

TEST(SynthesizeScene, PlanarStructureIsCoplanarAndBoxesAreNot) {
  SyntheticSceneOptions options;
  options.structure = SyntheticStructure::kPlane;
  const Eigen::Vector3d plane = CenteredSingularValues(SynthesizeScene(options).points3D);
  EXPECT_LT(plane(2), 1e-12 * plane(0));
  EXPECT_GT(plane(1), 0.5 * plane(0));  // A spread-out square, not a line.

  options.structure = SyntheticStructure::kBoxes;
  const Eigen::Vector3d boxes = CenteredSingularValues(SynthesizeScene(options).points3D);
  EXPECT_GT(boxes(2), 0.2 * boxes(0));
}

TEST(SynthesizeScene, PlanarSceneIsObservedByAllCameras) {
  SyntheticSceneOptions options;
  options.structure = SyntheticStructure::kPlane;
  for (const SyntheticImage& image : SynthesizeScene(options).images) {
    EXPECT_GT(image.observations.size(), 100u);
  }
}

TEST(SynthesizeScene, PureRotationHasOneCentreAndDistinctRotations) {
  SyntheticSceneOptions options;
  options.layout = SyntheticCameraLayout::kPureRotation;
  const SyntheticScene scene = SynthesizeScene(options);
  const std::vector<Eigen::Vector3d> centers = Centers(scene);
  for (std::size_t i = 0; i < scene.images.size(); ++i) {
    EXPECT_LT((centers[i] - centers[0]).norm(), 1e-12);
    EXPECT_GT(scene.images[i].observations.size(), 50u);
    for (std::size_t j = 0; j < i; ++j) {
      EXPECT_GT(
          RotationDifferenceDeg(scene.images[i].cam_from_world, scene.images[j].cam_from_world),
          0.5);
    }
  }
  // The relative pose between any two views is a pure rotation.
  EXPECT_LT(RelativePose(scene, 0, 3).translation.norm(), 1e-12);
}

TEST(SynthesizeScene, LineLayoutHasCollinearDistinctCentres) {
  SyntheticSceneOptions options;
  options.layout = SyntheticCameraLayout::kLine;
  options.line_length = 5.0;
  const std::vector<Eigen::Vector3d> centers = Centers(SynthesizeScene(options));
  const Eigen::Vector3d singular_values = CenteredSingularValues(centers);
  EXPECT_LT(singular_values(1), 1e-12 * singular_values(0));
  EXPECT_NEAR((centers.back() - centers.front()).norm(), 5.0, 1e-12);
  for (std::size_t i = 1; i < centers.size(); ++i) {
    EXPECT_NEAR((centers[i] - centers[i - 1]).norm(), 5.0 / (centers.size() - 1), 1e-12);
  }
}

TEST(SynthesizeScene, RingAndArcLayouts) {
  SyntheticSceneOptions options;
  options.num_cameras = 8;
  options.camera_distance = 5.0;
  options.camera_height = 2.0;
  const std::vector<Eigen::Vector3d> ring = Centers(SynthesizeScene(options));
  const Eigen::Vector3d singular_values = CenteredSingularValues(ring);
  EXPECT_GT(singular_values(1), 0.5 * singular_values(0));    // Not collinear...
  EXPECT_LT(singular_values(2), 1e-12 * singular_values(0));  // ...but on a horizontal circle.
  for (std::size_t i = 0; i < ring.size(); ++i) {
    EXPECT_NEAR(ring[i].head<2>().norm(), 5.0, 1e-12);
    EXPECT_NEAR(ring[i].z(), 2.0, 1e-12);
    const Eigen::Vector3d next = ring[(i + 1) % ring.size()];
    EXPECT_NEAR(std::acos(ring[i].head<2>().normalized().dot(next.head<2>().normalized())),
                M_PI / 4, 1e-9);
  }

  options.layout = SyntheticCameraLayout::kArc;
  options.arc_deg = 100.0;
  const std::vector<Eigen::Vector3d> arc = Centers(SynthesizeScene(options));
  EXPECT_NEAR(std::acos(arc.front().head<2>().normalized().dot(arc.back().head<2>().normalized())) *
                  180.0 / M_PI,
              100.0, 1e-9);
}

TEST(SynthesizeScene, EveryLayoutLooksAtTheStructure) {
  for (const auto layout :
       {SyntheticCameraLayout::kRing, SyntheticCameraLayout::kArc, SyntheticCameraLayout::kLine,
        SyntheticCameraLayout::kRandom, SyntheticCameraLayout::kPureRotation}) {
    SyntheticSceneOptions options;
    options.layout = layout;
    const SyntheticScene scene = SynthesizeScene(options);
    for (const SyntheticImage& image : scene.images) {
      EXPECT_GE(image.cam_from_world.CenterInWorld().norm(), options.camera_distance - 1e-9);
      // Pure rotation looks at targets spread over the structure, the others at its centre.
      const auto origin = ProjectPoint(image, Eigen::Vector3d::Zero());
      ASSERT_TRUE(origin.has_value()) << SyntheticCameraLayoutName(layout);
      if (layout != SyntheticCameraLayout::kPureRotation) {
        EXPECT_TRUE(image.camera.InImage(*origin)) << SyntheticCameraLayoutName(layout);
      }
      EXPECT_GT(image.observations.size(), 50u) << SyntheticCameraLayoutName(layout);
    }
  }
}

TEST(SynthesizeScene, SharedIntrinsicsAreIdentical) {
  SyntheticSceneOptions options;
  options.k1 = -0.05;
  const SyntheticScene scene = SynthesizeScene(options);
  for (const SyntheticImage& image : scene.images) {
    EXPECT_EQ(image.camera_id, 0);
    EXPECT_EQ(image.camera.focal, 500.0);
    EXPECT_EQ(image.camera.cx, 319.5);
    EXPECT_EQ(image.camera.cy, 239.5);
    EXPECT_EQ(image.camera.k1, -0.05);
    EXPECT_EQ(image.camera.k2, 0.0);
  }
}

TEST(SynthesizeScene, VariedIntrinsicsStayInRange) {
  SyntheticSceneOptions options;
  options.shared_intrinsics = false;
  options.focal_variation = 0.1;
  options.principal_point_variation = 5.0;
  options.distortion_variation = 0.03;
  const SyntheticScene scene = SynthesizeScene(options);
  std::set<double> focals;
  for (int i = 0; i < static_cast<int>(scene.images.size()); ++i) {
    const Camera& camera = scene.images[i].camera;
    EXPECT_EQ(scene.images[i].camera_id, i);
    EXPECT_NEAR(camera.focal, 500.0, 50.0);
    EXPECT_NEAR(camera.cx, 319.5, 5.0);
    EXPECT_NEAR(camera.cy, 239.5, 5.0);
    EXPECT_NEAR(camera.k1, 0.0, 0.03);
    EXPECT_NEAR(camera.k2, 0.0, 0.03);
    EXPECT_EQ(camera.width, 640);
    focals.insert(camera.focal);
  }
  EXPECT_EQ(focals.size(), scene.images.size());
}

TEST(SynthesizeScene, ReproducibleFromSeed) {
  SyntheticSceneOptions options;
  options.pixel_noise_stddev = 1.0;
  options.outlier_fraction = 0.1;
  options.layout = SyntheticCameraLayout::kRandom;
  options.seed = 42;
  const SyntheticScene a = SynthesizeScene(options);
  const SyntheticScene b = SynthesizeScene(options);
  ASSERT_EQ(a.points3D.size(), b.points3D.size());
  for (std::size_t i = 0; i < a.points3D.size(); ++i) EXPECT_EQ(a.points3D[i], b.points3D[i]);
  ASSERT_EQ(a.images.size(), b.images.size());
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    EXPECT_EQ(a.images[i].cam_from_world.ToMatrix(), b.images[i].cam_from_world.ToMatrix());
    ASSERT_EQ(a.images[i].observations.size(), b.images[i].observations.size());
    for (std::size_t j = 0; j < a.images[i].observations.size(); ++j) {
      EXPECT_EQ(a.images[i].observations[j].pixel, b.images[i].observations[j].pixel);
      EXPECT_EQ(a.images[i].observations[j].is_outlier, b.images[i].observations[j].is_outlier);
    }
  }

  options.seed = 43;
  const SyntheticScene c = SynthesizeScene(options);
  EXPECT_GT((a.points3D[0] - c.points3D[0]).norm(), 1e-3);
  EXPECT_GT(
      (a.images[0].cam_from_world.CenterInWorld() - c.images[0].cam_from_world.CenterInWorld())
          .norm(),
      1e-3);
}

TEST(SynthesizeScene, NoiseDoesNotMoveGeometry) {
  SyntheticSceneOptions options;
  const SyntheticScene clean = SynthesizeScene(options);
  options.pixel_noise_stddev = 2.0;
  options.outlier_fraction = 0.2;
  const SyntheticScene noisy = SynthesizeScene(options);
  for (std::size_t i = 0; i < clean.points3D.size(); ++i) {
    EXPECT_EQ(clean.points3D[i], noisy.points3D[i]);
  }
  for (std::size_t i = 0; i < clean.images.size(); ++i) {
    EXPECT_EQ(clean.images[i].cam_from_world.ToMatrix(), noisy.images[i].cam_from_world.ToMatrix());
    EXPECT_EQ(clean.images[i].observations.size(), noisy.images[i].observations.size());
  }
}

TEST(FindCorrespondences, PairsObservationsOfTheSamePoint) {
  SyntheticSceneOptions options;
  options.outlier_fraction = 0.2;
  const SyntheticScene scene = SynthesizeScene(options);
  const auto& observations1 = scene.images[0].observations;
  const auto& observations2 = scene.images[1].observations;
  std::set<int> points1, points2;
  for (const auto& o : observations1) points1.insert(o.source_point);
  for (const auto& o : observations2) points2.insert(o.source_point);
  int num_common = 0;
  for (const int p : points1) num_common += points2.count(p);

  const std::vector<SyntheticCorrespondence> correspondences = FindCorrespondences(scene, 0, 1);
  ASSERT_EQ(static_cast<int>(correspondences.size()), num_common);
  ASSERT_GT(num_common, 100);
  int num_outliers = 0;
  for (const SyntheticCorrespondence& c : correspondences) {
    const SyntheticObservation& o1 = observations1[c.observation1];
    const SyntheticObservation& o2 = observations2[c.observation2];
    EXPECT_EQ(o1.source_point, o2.source_point);
    EXPECT_EQ(c.pixel1, o1.pixel);
    EXPECT_EQ(c.pixel2, o2.pixel);
    EXPECT_EQ(c.is_outlier, o1.is_outlier || o2.is_outlier);
    if (c.is_outlier) {
      ++num_outliers;
      EXPECT_EQ(c.point_index, -1);
    } else {
      EXPECT_EQ(c.point_index, o1.source_point);
    }
  }
  // Each side is an outlier with probability 0.2: about 36 % of the pairs.
  EXPECT_GT(num_outliers, 0.2 * num_common);
  EXPECT_LT(num_outliers, 0.5 * num_common);
}

TEST(FindCorrespondences, InliersSatisfyRelativePose) {
  const SyntheticScene scene = SynthesizeScene(SyntheticSceneOptions());
  const Rigid3d cam2_from_cam1 = RelativePose(scene, 0, 2);
  for (const SyntheticCorrespondence& c : FindCorrespondences(scene, 0, 2)) {
    // The ray of pixel1 at the point's depth in camera 1, moved into camera 2, projects to
    // pixel2.
    const Eigen::Vector3d point = scene.points3D[c.point_index];
    const double depth1 = (scene.images[0].cam_from_world * point).z();
    const Eigen::Vector3d point_in_cam1 = *scene.images[0].camera.CamFromImg(c.pixel1) * depth1;
    const Eigen::Vector2d pixel2 =
        *scene.images[2].camera.ImgFromCam(cam2_from_cam1 * point_in_cam1);
    EXPECT_LT((pixel2 - c.pixel2).norm(), 1e-8);
  }
}

TEST(FindCorrespondences, RejectsBadImageIndex) {
  const SyntheticScene scene = SynthesizeScene(SyntheticSceneOptions());
  EXPECT_THROW(FindCorrespondences(scene, 0, 10), CheckError);
  EXPECT_THROW(FindCorrespondences(scene, -1, 0), CheckError);
  EXPECT_THROW(RelativePose(scene, 0, 10), CheckError);
}

}  // namespace
}  // namespace reconduit
