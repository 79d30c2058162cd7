#include "core/io/reconstruction_json.h"

#include "core/io/file_util.h"
#include "core/io/sparse_model_test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing_util::DistortedSceneOptions;
using testing_util::FreshTestFolder;
using testing_util::SyntheticReconstruction;

// Bit-for-bit equality of two reconstructions, field by field.
void ExpectIdentical(const Reconstruction& a, const Reconstruction& b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, ca] : a.cameras) {
    ASSERT_TRUE(b.cameras.contains(id)) << "camera " << id;
    const Camera& cb = b.cameras.at(id);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.focal, cb.focal);
    EXPECT_EQ(ca.cx, cb.cx);
    EXPECT_EQ(ca.cy, cb.cy);
    EXPECT_EQ(ca.k1, cb.k1);
    EXPECT_EQ(ca.k2, cb.k2);
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (const auto& [id, ia] : a.images) {
    ASSERT_TRUE(b.images.contains(id)) << "image " << id;
    const RegisteredImage& ib = b.images.at(id);
    EXPECT_EQ(ia.image_id, ib.image_id);
    EXPECT_EQ(ia.camera_id, ib.camera_id);
    EXPECT_EQ(ia.name, ib.name);
    EXPECT_EQ(ia.cam_from_world.rotation.coeffs(), ib.cam_from_world.rotation.coeffs());
    EXPECT_EQ(ia.cam_from_world.translation, ib.cam_from_world.translation);
    EXPECT_EQ(ia.keypoints, ib.keypoints);
    EXPECT_EQ(ia.point_for_keypoint, ib.point_for_keypoint);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (const auto& [id, pa] : a.points) {
    ASSERT_TRUE(b.points.contains(id)) << "point " << id;
    const Point3D& pb = b.points.at(id);
    EXPECT_EQ(pa.xyz_in_world, pb.xyz_in_world);
    EXPECT_EQ(pa.rgb, pb.rgb);
    EXPECT_EQ(pa.error, pb.error);
    ASSERT_EQ(pa.observations.size(), pb.observations.size());
    for (std::size_t k = 0; k < pa.observations.size(); ++k) {
      EXPECT_EQ(pa.observations[k].image_id, pb.observations[k].image_id);
      EXPECT_EQ(pa.observations[k].keypoint, pb.observations[k].keypoint);
    }
  }
}

TEST(ReconstructionJson, RoundTripIsExact) {
  const Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  ASSERT_GT(rec.points.size(), 50u);
  ASSERT_GT(rec.cameras.size(), 1u);
  const fs::path path = FreshTestFolder() / "model_0.json";
  ASSERT_TRUE(WriteReconstructionJson(path, rec).ok());
  Result<Reconstruction> read = ReadReconstructionJson(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdentical(rec, *read);

  // The id counter continues after the largest id, so new points never overwrite old ones.
  const int max_id = read->points.rbegin()->first;
  Reconstruction extended = *read;
  EXPECT_EQ(extended.AddPoint(Eigen::Vector3d::Zero(), {}), max_id + 1);
  fs::remove_all(path.parent_path());
}

TEST(ReconstructionJson, IsOneCompactLineWithVersion) {
  const Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  Result<std::string> text = ReconstructionToJson(rec);
  ASSERT_TRUE(text.ok()) << text.status();
  EXPECT_EQ(std::count(text->begin(), text->end(), '\n'), 1) << "no pretty-printing";
  EXPECT_EQ(text->back(), '\n');
  EXPECT_EQ(text->find(": "), std::string::npos);
  const json root = json::parse(*text);
  EXPECT_EQ(root.at("version"), 1);
  EXPECT_EQ(root.at("format"), "reconduit-reconstruction");
  EXPECT_EQ(root.at("points").size(), rec.points.size());
  // Compactness: a generous bound per stored number (keypoints dominate).
  std::size_t numbers = 0;
  for (const auto& [id, image] : rec.images) numbers += 2 * image.keypoints.size() + 7;
  numbers += 6 * rec.points.size() + 2 * rec.NumObservations();
  EXPECT_LT(text->size(), 24 * numbers);
}

TEST(ReconstructionJson, NonFiniteErrorBecomesInfinity) {
  Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  const int id = rec.points.begin()->first;
  rec.points.at(id).error = std::numeric_limits<double>::infinity();
  Result<std::string> text = ReconstructionToJson(rec);
  ASSERT_TRUE(text.ok()) << text.status();
  Result<Reconstruction> read = ReconstructionFromJson(*text);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->points.at(id).error, std::numeric_limits<double>::infinity());
}

TEST(ReconstructionJson, EmptyReconstructionRoundTrips) {
  Result<std::string> text = ReconstructionToJson(Reconstruction());
  ASSERT_TRUE(text.ok());
  Result<Reconstruction> read = ReconstructionFromJson(*text);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_TRUE(read->cameras.empty());
  EXPECT_TRUE(read->images.empty());
  EXPECT_TRUE(read->points.empty());
}

TEST(ReconstructionJson, WriterRefusesAnInconsistentReconstruction) {
  Reconstruction rec = SyntheticReconstruction(DistortedSceneOptions());
  // The point still lists the observation but the image no longer points back at it.
  const Observation o = rec.points.begin()->second.observations.front();
  rec.images.at(o.image_id).point_for_keypoint[o.keypoint] = kInvalidId;
  Result<std::string> text = ReconstructionToJson(rec);
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(text.status().message().find("point_for_keypoint"), std::string::npos) << text.status();
}

// Applies `edit` to the JSON of the test reconstruction and returns the reader's status.
template <typename Edit>
Status ReadEdited(Edit edit) {
  Result<std::string> text = ReconstructionToJson(SyntheticReconstruction(DistortedSceneOptions()));
  THROW_CHECK(text.ok());
  json root = json::parse(*text);
  edit(root);
  return ReconstructionFromJson(root.dump()).status();
}

void ExpectError(const Status& status, const std::string& fragment) {
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status;
  EXPECT_NE(status.message().find(fragment), std::string::npos)
      << "expected '" << fragment << "' in: " << status.message();
}

TEST(ReconstructionJson, BadFilesGiveClearErrors) {
  ExpectError(ReconstructionFromJson("{\"format\": ").status(), "not valid JSON");
  ExpectError(ReconstructionFromJson("[1, 2]").status(), "expected an object");
  ExpectError(ReadEdited([](json& j) { j["version"] = 2; }), "unsupported version 2");
  ExpectError(ReadEdited([](json& j) { j["format"] = "something-else"; }), "format");
  ExpectError(ReadEdited([](json& j) { j["images"][2].erase("rotation"); }),
              "images[2]: missing \"rotation\"");
  ExpectError(ReadEdited([](json& j) { j["images"][0]["keypoints"].push_back(1.0); }),
              "images[0].keypoints");
  ExpectError(ReadEdited([](json& j) { j["images"][0]["camera_id"] = 999; }), "unknown camera 999");
  ExpectError(ReadEdited([](json& j) { j["cameras"][0]["focal"] = -1.0; }), "cameras[0]");
  ExpectError(ReadEdited([](json& j) { j["points"][3]["track"][0] = 999; }), "unknown image 999");
  ExpectError(ReadEdited([](json& j) { j["points"][3]["track"][1] = 100000; }), "out of range");
  ExpectError(ReadEdited([](json& j) { j["points"][1]["id"] = j["points"][0]["id"]; }), "unique");
  ExpectError(ReadEdited([](json& j) { j["points"][0]["rgb"][1] = 300; }), "points[0].rgb");
  ExpectError(ReadEdited([](json& j) { j["points"][0]["xyz"][1] = "x"; }), "expected a number");
}

TEST(ReconstructionJson, MissingFileIsNotFound) {
  const fs::path dir = FreshTestFolder();
  EXPECT_EQ(ReadReconstructionJson(dir / "missing.json").status().code(), StatusCode::kNotFound);
  ASSERT_TRUE(WriteFileAtomically(dir / "bad.json", "{}").ok());
  const Status status = ReadReconstructionJson(dir / "bad.json").status();
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("bad.json"), std::string::npos) << "names the file";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace reconduit
