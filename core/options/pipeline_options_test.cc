#include "core/options/pipeline_options.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

TEST(PipelineOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(PipelineOptions().Check(&error)) << error;
}

TEST(PipelineOptions, CheckNamesTheField) {
  PipelineOptions options;
  options.min_image_side = 3;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THAT(error, HasSubstr("min_image_side"));
  EXPECT_THAT(error, HasSubstr("[16, 10000]"));
}

TEST(ParsePipelineOptions, OverridesDefaults) {
  auto options = ParsePipelineOptionsText(R"({"min_image_side": 200, "use_exif": false})");
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->min_image_side, 200);
  EXPECT_FALSE(options->use_exif);
  EXPECT_EQ(options->max_image_pixels, PipelineOptions().max_image_pixels);
}

TEST(ParsePipelineOptions, EmptyAndNullMeanDefaults) {
  EXPECT_TRUE(ParsePipelineOptionsText("").ok());
  EXPECT_TRUE(ParsePipelineOptionsText("{}").ok());
  EXPECT_TRUE(ParsePipelineOptions(nlohmann::json()).ok());
}

TEST(ParsePipelineOptions, RejectsBadInputWithClearMessages) {
  struct Case {
    const char* text;
    const char* expected;
  };
  for (const Case& c : std::vector<Case>{
           {"{not json", "not valid JSON"},
           {"[1, 2]", "must be a JSON object"},
           {R"({"colour": 1})", "unknown option 'colour'"},
           {R"({"min_image_side": 5})",
            "option 'min_image_side' must be an integer in [16, 10000], got 5"},
           {R"({"min_image_side": 100.5})", "must be an integer"},
           {R"({"min_image_side": "100"})", "must be an integer"},
           {R"({"use_exif": 1})", "option 'use_exif' must be true or false"},
           {R"({"num_threads": -1})", "num_threads"},
           {R"({"principal_point": "free"})",
            "option 'principal_point' must be one of auto, center, refine; got \"free\""},
           {R"({"principal_point": true})", "option 'principal_point' must be one of"},
           {R"({"held_out_photos": "0001.jpg"})",
            "option 'held_out_photos' must be a list of at most 1000 distinct names"},
           {R"({"held_out_photos": [""]})", "strings of 1 to 255 bytes"},
           {R"({"held_out_photos": [3]})", "strings of 1 to 255 bytes"},
           {R"({"held_out_photos": ["a.jpg", "a.jpg"]})", "\"a.jpg\" appears twice"},
       }) {
    auto options = ParsePipelineOptionsText(c.text);
    ASSERT_FALSE(options.ok()) << c.text;
    EXPECT_EQ(options.status().code(), StatusCode::kInvalidArgument);
    EXPECT_THAT(options.status().message(), HasSubstr(c.expected)) << c.text;
  }
}

// Found by fuzz/options_fuzzer.cc (corpus: fuzz/corpus/options/number-overflow): a number too
// large for a double threw nlohmann's out_of_range out of ParsePipelineOptionsText.
TEST(ParsePipelineOptions, NumberOverflowIsAnError) {
  for (const char* text : {"6E452", R"({"max_image_pixels": 1e999})", "-1E400"}) {
    Result<PipelineOptions> options = PipelineOptions();
    ASSERT_NO_THROW(options = ParsePipelineOptionsText(text)) << text;
    ASSERT_FALSE(options.ok()) << text;
    EXPECT_EQ(options.status().code(), StatusCode::kInvalidArgument);
    EXPECT_THAT(options.status().message(), HasSubstr("not valid JSON")) << text;
  }
}

TEST(DescribePipelineOptions, ListsEveryOptionWithDefaultsAndRanges) {
  const nlohmann::json described = DescribePipelineOptions();
  ASSERT_EQ(described["options"].size(), PipelineOptionSpecs().size());
  const nlohmann::json& first = described["options"][0];
  EXPECT_EQ(first["name"], "min_image_side");
  EXPECT_EQ(first["type"], "integer");
  EXPECT_EQ(first["default"], 100);
  EXPECT_EQ(first["minimum"], 16);
  EXPECT_FALSE(first["help"].get<std::string>().empty());
  bool listed_choices = false;
  for (const nlohmann::json& option : described["options"]) {
    if (option["name"] != "principal_point") continue;
    EXPECT_EQ(option["type"], "string");
    EXPECT_EQ(option["default"], "auto");
    EXPECT_EQ(option["enum"], nlohmann::json::array({"auto", "center", "refine"}));
    listed_choices = true;
  }
  EXPECT_TRUE(listed_choices);
}

TEST(DescribePipelineOptions, MaxFeaturesUsesTheSharedDefaultAndRange) {
  const nlohmann::json described = DescribePipelineOptions();
  bool listed = false;
  for (const nlohmann::json& option : described["options"]) {
    if (option["name"] != "max_features") continue;
    EXPECT_EQ(option["default"], kDefaultMaxFeatures);
    EXPECT_EQ(option["minimum"], kMinMaxFeatures);
    EXPECT_EQ(option["maximum"], kMaxMaxFeatures);
    listed = true;
  }
  EXPECT_TRUE(listed);
  EXPECT_TRUE(ParsePipelineOptions({{"max_features", kMinMaxFeatures}}).ok());
  EXPECT_TRUE(ParsePipelineOptions({{"max_features", kMaxMaxFeatures}}).ok());
  EXPECT_FALSE(ParsePipelineOptions({{"max_features", kMinMaxFeatures - 1}}).ok());
  EXPECT_FALSE(ParsePipelineOptions({{"max_features", kMaxMaxFeatures + 1}}).ok());
}

TEST(ParsePipelineOptions, AcceptsEachChoice) {
  for (const std::string choice : {"auto", "center", "refine"}) {
    auto options = ParsePipelineOptions({{"principal_point", choice}});
    ASSERT_TRUE(options.ok()) << options.status();
    EXPECT_EQ(options->principal_point, choice);
  }
}

TEST(PipelineOptionsToJson, RoundTrips) {
  PipelineOptions options;
  options.num_threads = 3;
  options.use_exif = false;
  options.held_out_photos = {"0004.jpg", "dir/photo 7.JPG"};
  auto parsed = ParsePipelineOptions(PipelineOptionsToJson(options));
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(parsed->num_threads, 3);
  EXPECT_FALSE(parsed->use_exif);
  EXPECT_EQ(parsed->held_out_photos, options.held_out_photos);
}

TEST(ParsePipelineOptions, HeldOutPhotosAreAListOfNames) {
  auto options = ParsePipelineOptionsText(R"({"held_out_photos": ["0001.jpg", "0007.jpg"]})");
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->held_out_photos, (std::vector<std::string>{"0001.jpg", "0007.jpg"}));
  EXPECT_TRUE(PipelineOptions().held_out_photos.empty());
  nlohmann::json many = nlohmann::json::array();
  for (int i = 0; i <= 1000; ++i) many.push_back(std::to_string(i) + ".jpg");
  EXPECT_FALSE(ParsePipelineOptions({{"held_out_photos", many}}).ok());
  many.erase(many.begin());
  EXPECT_TRUE(ParsePipelineOptions({{"held_out_photos", many}}).ok());
  const nlohmann::json described = DescribePipelineOptions();  // Outlives the loop.
  for (const nlohmann::json& option : described["options"]) {
    if (option["name"] == "held_out_photos") {
      EXPECT_EQ(option["type"], "array");
      EXPECT_EQ(option["default"], nlohmann::json::array());
    }
  }
}

// Options that only change speed or what the packaging stage packs leave finished stages
// valid: the lean zip can be asked for on a restart without recomputing the model.
TEST(OptionAffectsResults, FalseOnlyForSpeedAndPackaging) {
  EXPECT_FALSE(OptionAffectsResults("num_threads"));
  EXPECT_FALSE(OptionAffectsResults("package_dense_files"));
  EXPECT_TRUE(OptionAffectsResults("texture"));
  EXPECT_TRUE(OptionAffectsResults("dense_max_image_side"));
  auto lean = ParsePipelineOptions({{"package_dense_files", false}});
  ASSERT_TRUE(lean.ok()) << lean.status();
  EXPECT_FALSE(lean->package_dense_files);
  EXPECT_TRUE(PipelineOptions().package_dense_files);
}

}  // namespace
}  // namespace reconduit
