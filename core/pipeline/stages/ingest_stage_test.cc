#include "core/pipeline/stages/ingest_stage.h"

#include <gtest/gtest.h>

namespace reconduit {
namespace {

IngestedImage Sample() {
  IngestedImage image;
  image.index = 3;
  image.name = "IMG_4.JPG";
  image.path = "/data/input/0004.jpg";
  image.photo.width = 640;
  image.photo.height = 480;
  image.photo.exif_focal_px = 512.5;
  image.photo.focal_source = "35mm_equivalent";
  image.photo.make = "Canon";
  image.photo.model = "EOS 5D";
  image.camera_key = "Canon|EOS 5D|640x480";
  return image;
}

// work/ingest/images.json keeps its field names; the metadata round-trips (bytes aside, which
// the file does not hold).
TEST(IngestedImage, JsonFieldNamesAndRoundTrip) {
  const IngestedImage image = Sample();
  const nlohmann::json json = image.ToJson();
  EXPECT_EQ(json, nlohmann::json::parse(R"({
    "index": 3, "name": "IMG_4.JPG", "path": "/data/input/0004.jpg", "accepted": true,
    "width": 640, "height": 480, "camera_key": "Canon|EOS 5D|640x480",
    "exif_focal_px": 512.5, "focal_source": "35mm_equivalent",
    "camera_make": "Canon", "camera_model": "EOS 5D"})"));
  const IngestedImage back = IngestedImage::FromJson(json);
  EXPECT_EQ(back.index, image.index);
  EXPECT_EQ(back.name, image.name);
  EXPECT_EQ(back.path, image.path);
  EXPECT_EQ(back.camera_key, image.camera_key);
  EXPECT_EQ(back.photo, image.photo);
}

TEST(IngestedImage, RefusedPhotoKeepsItsReasonAndOmitsEmptyFields) {
  IngestedImage image;
  image.index = 0;
  image.name = "notes.jpg";
  image.path = "notes.jpg";
  image.photo.accepted = false;
  image.photo.reason = "not a JPEG, PNG or TIFF image";
  image.camera_key = "||0x0";
  const nlohmann::json json = image.ToJson();
  EXPECT_EQ(json["accepted"], false);
  EXPECT_EQ(json["reason"], "not a JPEG, PNG or TIFF image");
  EXPECT_FALSE(json.contains("exif_focal_px"));
  EXPECT_FALSE(json.contains("focal_source"));
  EXPECT_FALSE(json.contains("camera_make"));
  EXPECT_FALSE(json.contains("camera_model"));
  EXPECT_EQ(IngestedImage::FromJson(json).photo, image.photo);
}

}  // namespace
}  // namespace reconduit
