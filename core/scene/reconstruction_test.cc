#include "core/scene/reconstruction.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

// Three images sharing one camera, each with three keypoints.
Reconstruction ThreeImages() {
  Reconstruction model;
  model.cameras[0] = Camera::FromFocal(640, 480, 500.0);
  for (int id = 0; id < 3; ++id) {
    RegisteredImage& image = model.images[id];
    image.image_id = id;
    image.camera_id = 0;
    image.keypoints.assign(3, Eigen::Vector2d(320, 240));
    image.point_for_keypoint.assign(3, kInvalidId);
  }
  return model;
}

TEST(Reconstruction, DeleteImageRemovesItsObservationsAndOrphanedPoints) {
  Reconstruction model = ThreeImages();
  const int seen_by_all = model.AddPoint(Eigen::Vector3d(0, 0, 5), {{0, 0}, {1, 0}, {2, 0}});
  const int seen_by_0_and_1 = model.AddPoint(Eigen::Vector3d(1, 0, 5), {{0, 1}, {1, 1}});
  const int seen_by_1_and_2 = model.AddPoint(Eigen::Vector3d(0, 1, 5), {{1, 2}, {2, 2}});

  model.DeleteImage(0);
  EXPECT_EQ(model.images.count(0), 0u);
  EXPECT_EQ(model.cameras.count(0), 1u);  // Shared by the others.
  ASSERT_EQ(model.points.count(seen_by_all), 1u);
  EXPECT_EQ(model.points.at(seen_by_all).observations.size(), 2u);
  EXPECT_EQ(model.points.count(seen_by_0_and_1), 0u);  // One observation left: gone.
  EXPECT_EQ(model.images.at(1).point_for_keypoint[1], kInvalidId);
  EXPECT_EQ(model.points.count(seen_by_1_and_2), 1u);
  EXPECT_EQ(model.NumObservations(), 4u);
  for (const auto& [id, point] : model.points) {
    for (const Observation& o : point.observations) EXPECT_NE(o.image_id, 0);
  }
  EXPECT_THROW(model.DeleteImage(0), std::out_of_range);
}

}  // namespace
}  // namespace reconduit
