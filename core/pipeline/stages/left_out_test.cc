#include "core/pipeline/stages/left_out.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace reconduit {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

MapperInput InputOf(int photos, const std::vector<std::pair<int, int>>& pairs) {
  MapperInput input;
  for (int id = 0; id < photos; ++id) input.images[id].name = "p" + std::to_string(id) + ".jpg";
  for (const auto& [a, b] : pairs) {
    MapperPair pair;
    pair.image1 = a;
    pair.image2 = b;
    input.pairs.push_back(pair);
  }
  return input;
}

Reconstruction ModelOf(const std::vector<int>& ids) {
  Reconstruction model;
  for (int id : ids) model.images[id].image_id = id;
  return model;
}

TEST(LeftOutTest, EveryPhotoInTheModelSaysNothing) {
  const MapperInput input = InputOf(3, {{0, 1}, {1, 2}});
  const LeftOutPhotos left = FindLeftOutPhotos(input, {ModelOf({0, 1, 2})});
  EXPECT_TRUE(left.empty());
  EXPECT_EQ(left.Note(), "");
  EXPECT_EQ(left.ToJson()["note"], "");
}

TEST(LeftOutTest, SeparatesOtherGroupsUnmatchedAndUnplacedPhotos) {
  // 0-1-2 the model, 3-4 a group of their own, 5 matched 2 but was not placed, 6 matched
  // nothing.
  const MapperInput input = InputOf(7, {{0, 1}, {1, 2}, {3, 4}, {2, 5}});
  const LeftOutPhotos left = FindLeftOutPhotos(input, {ModelOf({0, 1, 2}), ModelOf({3, 4})});
  EXPECT_EQ(left.photos, 7);
  EXPECT_EQ(left.registered, 3);
  ASSERT_EQ(left.other_groups.size(), 1u);
  EXPECT_THAT(left.other_groups[0], ElementsAre("p3.jpg", "p4.jpg"));
  EXPECT_THAT(left.not_placed, ElementsAre("p5.jpg"));
  EXPECT_THAT(left.unmatched, ElementsAre("p6.jpg"));
  const std::string note = left.Note();
  EXPECT_THAT(note, HasSubstr("3 of 7 photos are in the model."));
  EXPECT_THAT(note,
              HasSubstr("A separate group of 2 photos (p3.jpg, p4.jpg) was placed on its own"));
  EXPECT_THAT(note, HasSubstr("1 photo (p6.jpg) matched no other photo"));
  EXPECT_THAT(note, HasSubstr("1 photo (p5.jpg) matched other photos but could not be placed"));
  const nlohmann::json json = left.ToJson();
  EXPECT_EQ(json["other_groups"][0][1], "p4.jpg");
  EXPECT_EQ(json["note"], note);
}

TEST(LeftOutTest, NoModelLeavesEveryMatchedPhotoUnplaced) {
  const MapperInput input = InputOf(3, {{0, 1}});
  const LeftOutPhotos left = FindLeftOutPhotos(input, {});
  EXPECT_EQ(left.registered, 0);
  EXPECT_THAT(left.other_groups, IsEmpty());
  EXPECT_THAT(left.not_placed, ElementsAre("p0.jpg", "p1.jpg"));
  EXPECT_THAT(left.unmatched, ElementsAre("p2.jpg"));
}

TEST(LeftOutTest, LongListsAreShortenedInTheNoteOnly) {
  const MapperInput input = InputOf(12, {});
  const LeftOutPhotos left = FindLeftOutPhotos(input, {ModelOf({0})});
  EXPECT_EQ(left.unmatched.size(), 11u);
  EXPECT_THAT(left.Note(), HasSubstr("11 photos (p1.jpg, p2.jpg, p3.jpg, p4.jpg, p5.jpg, p6.jpg "
                                     "and 5 more) matched no other photo"));
  EXPECT_EQ(left.ToJson()["unmatched"].size(), 11u);
}

}  // namespace
}  // namespace reconduit
