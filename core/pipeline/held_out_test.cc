#include "core/pipeline/held_out.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

TEST(CheckHeldOutPhotos, AcceptsKnownNamesAndNamesTheUnknownOnes) {
  const std::vector<std::string> photos = {"0000.jpg", "0001.jpg", "0002.jpg", "0003.jpg"};
  EXPECT_TRUE(CheckHeldOutPhotos({}, photos).ok());
  EXPECT_TRUE(CheckHeldOutPhotos({"0001.jpg", "0003.jpg"}, photos).ok());
  const Status unknown = CheckHeldOutPhotos({"0001.jpg", "0001", "x.png"}, photos);
  EXPECT_EQ(unknown.code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(unknown.message(), HasSubstr("'0001', 'x.png'"));
  EXPECT_THAT(unknown.message(), HasSubstr("e.g. '0000.jpg'"));
  const Status too_many = CheckHeldOutPhotos({"0000.jpg", "0001.jpg", "0002.jpg"}, photos);
  EXPECT_EQ(too_many.code(), StatusCode::kInvalidArgument);
  EXPECT_THAT(too_many.message(), HasSubstr("holds 3 of 4 photos"));
}

TEST(WithoutHeldOutPhotos, DropsTheirImagesAndObservations) {
  Reconstruction model;
  model.cameras[0] = Camera::FromFocal(640, 480, 500.0);
  for (int id = 0; id < 3; ++id) {
    RegisteredImage& image = model.images[id];
    image.image_id = id;
    image.camera_id = 0;
    image.name = "p" + std::to_string(id) + ".jpg";
    image.keypoints.assign(2, Eigen::Vector2d(1, 1));
    image.point_for_keypoint.assign(2, kInvalidId);
  }
  model.AddPoint(Eigen::Vector3d(0, 0, 4), {{0, 0}, {1, 0}, {2, 0}});
  model.AddPoint(Eigen::Vector3d(0, 1, 4), {{0, 1}, {1, 1}});
  const Reconstruction kept = WithoutHeldOutPhotos(model, {"p1.jpg"});
  EXPECT_EQ(kept.images.size(), 2u);
  EXPECT_EQ(kept.images.count(1), 0u);
  EXPECT_EQ(kept.points.size(), 1u);
  EXPECT_EQ(kept.NumObservations(), 2u);
  EXPECT_EQ(model.images.size(), 3u);  // The input is unchanged.
  EXPECT_TRUE(IsHeldOut({"p1.jpg"}, "p1.jpg"));
  EXPECT_FALSE(IsHeldOut({"p1.jpg"}, "p1"));
}

}  // namespace
}  // namespace reconduit
