#include "server/http/range.h"

#include <gtest/gtest.h>

namespace reconduit::server {
namespace {

using Kind = RangeRequest::Kind;

void ExpectPartial(std::string_view header,
                   std::uint64_t size,
                   std::uint64_t offset,
                   std::uint64_t length) {
  SCOPED_TRACE(std::string(header));
  const RangeRequest range = ParseRangeHeader(header, size);
  ASSERT_EQ(range.kind, Kind::kPartial);
  EXPECT_EQ(range.slice.offset, offset);
  EXPECT_EQ(range.slice.length, length);
}

TEST(ParseRangeHeader, ClosedOpenAndSuffixRanges) {
  ExpectPartial("bytes=0-499", 1000, 0, 500);
  ExpectPartial("bytes=500-", 1000, 500, 500);
  ExpectPartial("bytes=-100", 1000, 900, 100);
  ExpectPartial("bytes=999-999", 1000, 999, 1);
  ExpectPartial(" Bytes=10-19 ", 1000, 10, 10);
}

TEST(ParseRangeHeader, ClampsPastTheEnd) {
  ExpectPartial("bytes=900-5000", 1000, 900, 100);
  ExpectPartial("bytes=-5000", 1000, 0, 1000);
  ExpectPartial("bytes=0-18446744073709551615", 10, 0, 10);
}

TEST(ParseRangeHeader, UnsatisfiableRanges) {
  EXPECT_EQ(ParseRangeHeader("bytes=1000-", 1000).kind, Kind::kUnsatisfiable);
  EXPECT_EQ(ParseRangeHeader("bytes=1000-2000", 1000).kind, Kind::kUnsatisfiable);
  EXPECT_EQ(ParseRangeHeader("bytes=-0", 1000).kind, Kind::kUnsatisfiable);
  EXPECT_EQ(ParseRangeHeader("bytes=0-", 0).kind, Kind::kUnsatisfiable);
  EXPECT_EQ(ParseRangeHeader("bytes=-5", 0).kind, Kind::kUnsatisfiable);
}

TEST(ParseRangeHeader, IgnoresWhatItDoesNotServe) {
  for (const char* header :
       {"", "bytes", "bytes=", "bytes=-", "items=0-1", "bytes=a-b", "bytes=5-1", "bytes=0-1,5-6",
        "bytes=1-2-3", "bytes=+1-2", "bytes=99999999999999999999-"}) {
    SCOPED_TRACE(header);
    EXPECT_EQ(ParseRangeHeader(header, 1000).kind, Kind::kWhole);
  }
}

TEST(ContentRangeHeader, FormatsInclusiveLastByte) {
  EXPECT_EQ(ContentRangeHeader({0, 500}, 1234), "bytes 0-499/1234");
  EXPECT_EQ(ContentRangeHeader({1233, 1}, 1234), "bytes 1233-1233/1234");
}

TEST(EntityTagListMatches, WeakComparisonOverLists) {
  const std::string etag = "\"abc\"";
  EXPECT_TRUE(EntityTagListMatches("\"abc\"", etag));
  EXPECT_TRUE(EntityTagListMatches("W/\"abc\"", etag));
  EXPECT_TRUE(EntityTagListMatches("\"x\", \"abc\"", etag));
  EXPECT_TRUE(EntityTagListMatches("*", etag));
  EXPECT_FALSE(EntityTagListMatches("\"abcd\"", etag));
  EXPECT_FALSE(EntityTagListMatches("abc", etag));
  EXPECT_FALSE(EntityTagListMatches("", etag));
}

// Issue 12: a weak W/ tag satisfied If-Range; RFC 9110 13.1.5 requires a strong match.
TEST(IfRangeMatches, StrongComparisonOnly) {
  const std::string etag = "\"abc\"";
  EXPECT_TRUE(IfRangeMatches("\"abc\"", etag));
  EXPECT_TRUE(IfRangeMatches("  \"abc\" ", etag));
  EXPECT_FALSE(IfRangeMatches("W/\"abc\"", etag));
  EXPECT_FALSE(IfRangeMatches("\"abc\"", "W/\"abc\""));
  EXPECT_FALSE(IfRangeMatches("\"abcd\"", etag));
  EXPECT_FALSE(IfRangeMatches("*", etag));
  EXPECT_FALSE(IfRangeMatches("\"x\", \"abc\"", etag));
  EXPECT_FALSE(IfRangeMatches("Tue, 01 Dec 2026 10:00:00 GMT", etag));
  EXPECT_FALSE(IfRangeMatches("", etag));
}

}  // namespace
}  // namespace reconduit::server
