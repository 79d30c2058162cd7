#include "server/http/url.h"

#include <gtest/gtest.h>

namespace reconduit::server {
namespace {

TEST(PercentDecode, DecodesEscapesAndKeepsOtherBytes) {
  EXPECT_EQ(PercentDecode("a%20b%2Fc%2fd"), "a b/c/d");
  EXPECT_EQ(PercentDecode("%e2%82%AC"), "\xe2\x82\xac");
  EXPECT_EQ(PercentDecode("plain"), "plain");
  EXPECT_EQ(PercentDecode(""), "");
}

TEST(PercentDecode, PlusIsSpaceOnlyWhenAsked) {
  EXPECT_EQ(PercentDecode("a+b"), "a+b");
  EXPECT_EQ(PercentDecode("a+b", /*plus_as_space=*/true), "a b");
  EXPECT_EQ(PercentDecode("a%2Bb", /*plus_as_space=*/true), "a+b");
}

TEST(PercentDecode, RejectsMalformedEscapesAndNul) {
  EXPECT_EQ(PercentDecode("%"), std::nullopt);
  EXPECT_EQ(PercentDecode("%2"), std::nullopt);
  EXPECT_EQ(PercentDecode("abc%"), std::nullopt);
  EXPECT_EQ(PercentDecode("%zz"), std::nullopt);
  EXPECT_EQ(PercentDecode("%g0"), std::nullopt);
  EXPECT_EQ(PercentDecode("a%00b"), std::nullopt);
}

TEST(SplitTarget, SeparatesPathAndQuery) {
  Result<TargetParts> parts = SplitTarget("/api/v1/jobs?limit=10&after=x");
  ASSERT_TRUE(parts.ok());
  EXPECT_EQ(parts->path, "/api/v1/jobs");
  EXPECT_EQ(parts->query, "limit=10&after=x");

  parts = SplitTarget("/healthz");
  ASSERT_TRUE(parts.ok());
  EXPECT_EQ(parts->path, "/healthz");
  EXPECT_EQ(parts->query, "");

  parts = SplitTarget("/a?b=1#frag");
  ASSERT_TRUE(parts.ok());
  EXPECT_EQ(parts->query, "b=1");
}

TEST(SplitTarget, RejectsNonOriginForms) {
  EXPECT_FALSE(SplitTarget("").ok());
  EXPECT_FALSE(SplitTarget("*").ok());
  EXPECT_FALSE(SplitTarget("http://example.com/").ok());
  EXPECT_FALSE(SplitTarget("example.com:443").ok());
}

TEST(ParseQuery, DecodesPairsInOrder) {
  Result<KeyValues> query = ParseQuery("after=12&name=a%20b+c&flag&&empty=&x=%3D%26");
  ASSERT_TRUE(query.ok());
  const KeyValues expected = {
      {"after", "12"}, {"name", "a b c"}, {"flag", ""}, {"empty", ""}, {"x", "=&"}};
  EXPECT_EQ(*query, expected);
}

TEST(ParseQuery, KeepsDuplicates) {
  Result<KeyValues> query = ParseQuery("a=1&a=2");
  ASSERT_TRUE(query.ok());
  ASSERT_EQ(query->size(), 2u);
  EXPECT_EQ((*query)[1].second, "2");
}

TEST(ParseQuery, EmptyQueryIsEmpty) {
  Result<KeyValues> query = ParseQuery("");
  ASSERT_TRUE(query.ok());
  EXPECT_TRUE(query->empty());
}

TEST(ParseQuery, RejectsMalformedEscapes) {
  Result<KeyValues> query = ParseQuery("ok=1&bad=%zz");
  ASSERT_FALSE(query.ok());
  EXPECT_EQ(query.status().code(), StatusCode::kInvalidArgument);
  EXPECT_FALSE(ParseQuery("%=1").ok());
}

TEST(DecodePathSegments, SplitsThenDecodes) {
  Result<std::vector<std::string>> segments = DecodePathSegments("/a/b%2Fc/%2e%2e/");
  ASSERT_TRUE(segments.ok());
  const std::vector<std::string> expected = {"a", "b/c", "..", ""};
  EXPECT_EQ(*segments, expected);

  segments = DecodePathSegments("/");
  ASSERT_TRUE(segments.ok());
  EXPECT_EQ(*segments, std::vector<std::string>{""});
}

TEST(DecodePathSegments, RejectsRelativeAndMalformed) {
  EXPECT_FALSE(DecodePathSegments("").ok());
  EXPECT_FALSE(DecodePathSegments("a/b").ok());
  EXPECT_FALSE(DecodePathSegments("/a%2").ok());
  EXPECT_FALSE(DecodePathSegments("/a%00").ok());
}

TEST(ParseHeaderValue, ParsesTokenAndParameters) {
  Result<HeaderValue> value =
      ParseHeaderValue("Multipart/Form-Data; Boundary=\"a b\\\"c\"; charset=utf-8 ;x=\"C:\\dir\"");
  ASSERT_TRUE(value.ok());
  EXPECT_EQ(value->value, "multipart/form-data");
  EXPECT_EQ(value->Param("boundary"), "a b\"c");
  EXPECT_EQ(value->Param("BOUNDARY"), "a b\"c");
  EXPECT_EQ(value->Param("charset"), "utf-8");
  // A backslash not before '"' or '\' is kept: browsers send Windows paths unescaped.
  EXPECT_EQ(value->Param("x"), "C:\\dir");
  EXPECT_EQ(value->Param("missing"), std::nullopt);
}

TEST(ParseHeaderValue, RejectsBrokenParameters) {
  EXPECT_FALSE(ParseHeaderValue("form-data; name=\"unterminated").ok());
  EXPECT_FALSE(ParseHeaderValue("form-data; novalue").ok());
  EXPECT_FALSE(ParseHeaderValue("form-data; =x").ok());
}

TEST(ParseHeaderValue, ValueWithoutParameters) {
  Result<HeaderValue> value = ParseHeaderValue(" application/json ");
  ASSERT_TRUE(value.ok());
  EXPECT_EQ(value->value, "application/json");
  EXPECT_TRUE(value->params.empty());
}

TEST(EqualsIgnoreCase, ComparesAscii) {
  EXPECT_TRUE(EqualsIgnoreCase("Content-Type", "content-type"));
  EXPECT_FALSE(EqualsIgnoreCase("Content-Type", "content-typ"));
  EXPECT_FALSE(EqualsIgnoreCase("a", "b"));
}

TEST(ConstantTimeEquals, ComparesContentAndLength) {
  EXPECT_TRUE(ConstantTimeEquals("s3cret", "s3cret"));
  EXPECT_TRUE(ConstantTimeEquals("", ""));
  EXPECT_FALSE(ConstantTimeEquals("s3cret", "s3creT"));
  EXPECT_FALSE(ConstantTimeEquals("s3cret", "s3cret2"));
  EXPECT_FALSE(ConstantTimeEquals("s3cret2", "s3cret"));
  EXPECT_FALSE(ConstantTimeEquals("", "x"));
  EXPECT_FALSE(ConstantTimeEquals("x", ""));
}

}  // namespace
}  // namespace reconduit::server
