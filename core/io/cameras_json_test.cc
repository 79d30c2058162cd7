#include "core/io/cameras_json.h"

#include "core/io/file_util.h"
#include "core/io/sparse_model_test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing_util::DistortedSceneOptions;
using testing_util::FreshTestFolder;
using testing_util::SourceDir;
using testing_util::SyntheticReconstruction;

json LoadSchema() {
  Result<std::string> text = ReadFile(SourceDir() / "schema" / "json" / "cameras.schema.json");
  THROW_CHECK(text.ok()) << text.status();
  return json::parse(*text);  // Throws, failing the test, when the schema is not JSON.
}

// A validator for the subset of JSON Schema 2020-12 that cameras.schema.json uses: type,
// const, required, properties, additionalProperties: false, items, minItems, maxItems,
// minimum, exclusiveMinimum, minLength and local $ref. It refuses any other keyword, so the
// schema cannot silently grow constraints this test does not check. Appends one message per
// violation to `errors`.
void Validate(const json& value,
              const json& schema,
              const json& root,
              const std::string& where,
              std::vector<std::string>* errors) {
  static const std::set<std::string> kKnown = {"$schema",
                                               "$id",
                                               "$defs",
                                               "title",
                                               "description",
                                               "type",
                                               "const",
                                               "required",
                                               "properties",
                                               "items",
                                               "additionalProperties",
                                               "minItems",
                                               "maxItems",
                                               "minimum",
                                               "exclusiveMinimum",
                                               "minLength",
                                               "$ref"};
  for (const auto& [key, unused] : schema.items()) {
    if (!kKnown.contains(key)) errors->push_back(where + ": unsupported keyword " + key);
  }
  if (schema.contains("$ref")) {
    const std::string ref = schema["$ref"];
    ASSERT_EQ(ref.rfind("#/", 0), 0u) << ref;
    Validate(value, root.at(json::json_pointer(ref.substr(1))), root, where, errors);
  }
  const auto fail = [&](const std::string& what) { errors->push_back(where + ": " + what); };
  if (schema.contains("type")) {
    const std::string type = schema["type"];
    const bool ok =
        (type == "object" && value.is_object()) || (type == "array" && value.is_array()) ||
        (type == "string" && value.is_string()) || (type == "number" && value.is_number()) ||
        (type == "integer" && value.is_number_integer()) ||
        (type == "boolean" && value.is_boolean());
    if (!ok) fail("expected " + type + ", found " + value.dump());
  }
  if (schema.contains("const") && value != schema["const"]) fail("expected const");
  if (schema.contains("minimum") && value.is_number() && value < schema["minimum"]) {
    fail("below minimum");
  }
  if (schema.contains("exclusiveMinimum") && value.is_number() &&
      value <= schema["exclusiveMinimum"]) {
    fail("not above exclusiveMinimum");
  }
  if (schema.contains("minLength") && value.is_string() &&
      value.get<std::string>().size() < schema["minLength"].get<std::size_t>()) {
    fail("too short");
  }
  if (value.is_object()) {
    for (const std::string key : schema.value("required", json::array())) {
      if (!value.contains(key)) fail("missing " + key);
    }
    const json properties = schema.value("properties", json::object());
    for (const auto& [key, item] : value.items()) {
      if (properties.contains(key)) {
        Validate(item, properties[key], root, where + "." + key, errors);
      } else if (schema.value("additionalProperties", true) == false) {
        fail("unexpected key " + key);
      }
    }
  }
  if (value.is_array()) {
    if (schema.contains("minItems") && value.size() < schema["minItems"]) fail("too few items");
    if (schema.contains("maxItems") && value.size() > schema["maxItems"]) fail("too many items");
    if (schema.contains("items")) {
      for (std::size_t i = 0; i < value.size(); ++i) {
        Validate(value[i], schema["items"], root, where + "[" + std::to_string(i) + "]", errors);
      }
    }
  }
}

std::vector<std::string> ValidateAgainstSchema(const json& document) {
  const json schema = LoadSchema();
  std::vector<std::string> errors;
  Validate(document, schema, schema, "(root)", &errors);
  return errors;
}

TEST(CamerasSchema, IsDraft202012Json) {
  const json schema = LoadSchema();
  EXPECT_EQ(schema.at("$schema"), "https://json-schema.org/draft/2020-12/schema");
  EXPECT_EQ(schema.at("type"), "object");
  EXPECT_EQ(schema.at("properties").at("version").at("const"), kCamerasJsonVersion);
}

class CamerasJsonTest : public ::testing::Test {
 protected:
  void SetUp() override { rec_ = SyntheticReconstruction(DistortedSceneOptions()); }
  Reconstruction rec_;
};

TEST_F(CamerasJsonTest, MatchesTheReconstructionAndTheSchema) {
  const fs::path dir = FreshTestFolder();
  const std::vector<std::string> unregistered = {"blurred.jpg", "IMG 0007.JPG"};
  ASSERT_TRUE(WriteCamerasJson(dir / "cameras.json", rec_, unregistered).ok());
  const json doc = json::parse(*ReadFile(dir / "cameras.json"));
  fs::remove_all(dir);

  const std::vector<std::string> errors = ValidateAgainstSchema(doc);
  EXPECT_TRUE(errors.empty()) << ::testing::PrintToString(errors);

  EXPECT_EQ(doc.at("version"), 1);
  EXPECT_NE(doc.at("coordinate_frame").get<std::string>().find("(0, 0)"), std::string::npos)
      << "states the pixel-centre convention";
  EXPECT_EQ(doc.at("unregistered"), json(unregistered));
  const json& images = doc.at("images");
  ASSERT_EQ(images.size(), rec_.images.size());
  std::size_t i = 0;
  for (const auto& [id, image] : rec_.images) {
    const json& j = images[i++];
    const std::set<std::string> expected_keys = {
        "name", "width", "height",   "focal",  "principal_point",
        "k1",   "k2",    "rotation", "center", "registered"};
    std::set<std::string> keys;
    for (const auto& [key, unused] : j.items()) keys.insert(key);
    EXPECT_EQ(keys, expected_keys);
    const Camera& camera = rec_.cameras.at(image.camera_id);
    EXPECT_EQ(j.at("name"), image.name);
    EXPECT_EQ(j.at("width"), camera.width);
    EXPECT_EQ(j.at("height"), camera.height);
    EXPECT_EQ(j.at("focal"), camera.focal);
    EXPECT_EQ(j.at("principal_point")[0], camera.cx) << "no 0.5 shift in cameras.json";
    EXPECT_EQ(j.at("principal_point")[1], camera.cy);
    EXPECT_EQ(j.at("k1"), camera.k1);
    EXPECT_EQ(j.at("k2"), camera.k2);
    EXPECT_EQ(j.at("registered"), true);
    Eigen::Matrix3d r;
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) r(row, col) = j.at("rotation")[row][col];
    }
    const Eigen::Matrix3d expected_r = image.cam_from_world.rotation.toRotationMatrix();
    EXPECT_LT((r - expected_r).cwiseAbs().maxCoeff(), 1e-15) << "row-major world-to-camera";
    const Eigen::Vector3d center(j.at("center")[0], j.at("center")[1], j.at("center")[2]);
    const Eigen::Vector3d t = image.cam_from_world.translation;
    EXPECT_LT((center - (-r.transpose() * t)).norm(), 1e-12);
    // And it is the camera centre: a world point there maps to the camera origin.
    EXPECT_LT((image.cam_from_world * center).norm(), 1e-9);
  }
}

TEST_F(CamerasJsonTest, SchemaCatchesBrokenDocuments) {
  Result<std::string> text = CamerasJson(rec_, {});
  ASSERT_TRUE(text.ok()) << text.status();
  const json good = json::parse(*text);
  ASSERT_TRUE(ValidateAgainstSchema(good).empty());
  json missing = good;
  missing["images"][0].erase("center");
  EXPECT_FALSE(ValidateAgainstSchema(missing).empty());
  json extra = good;
  extra["images"][1]["fov"] = 60;
  EXPECT_FALSE(ValidateAgainstSchema(extra).empty());
  json short_rotation = good;
  short_rotation["images"][0]["rotation"].erase(2);
  EXPECT_FALSE(ValidateAgainstSchema(short_rotation).empty());
  json bad_focal = good;
  bad_focal["images"][0]["focal"] = 0;
  EXPECT_FALSE(ValidateAgainstSchema(bad_focal).empty());
  json bad_version = good;
  bad_version["version"] = 2;
  EXPECT_FALSE(ValidateAgainstSchema(bad_version).empty());
}

TEST_F(CamerasJsonTest, RefusesAnInconsistentReconstruction) {
  rec_.images.at(0).camera_id = 12345;
  EXPECT_EQ(CamerasJson(rec_, {}).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reconduit
