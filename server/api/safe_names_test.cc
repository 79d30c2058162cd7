#include "server/api/safe_names.h"

#include <gtest/gtest.h>

#include <string>

namespace reconduit::server {
namespace {

TEST(SanitizeDisplayName, KeepsTheBaseNameOnly) {
  EXPECT_EQ(SanitizeDisplayName("IMG_0001.JPG", "x"), "IMG_0001.JPG");
  EXPECT_EQ(SanitizeDisplayName("../../etc/passwd", "x"), "passwd");
  EXPECT_EQ(SanitizeDisplayName("/abs/path/a.jpg", "x"), "a.jpg");
  EXPECT_EQ(SanitizeDisplayName("C:\\photos\\IMG 1.jpg", "x"), "IMG 1.jpg");
  EXPECT_EQ(SanitizeDisplayName("dir/..\\b.png", "x"), "b.png");
}

TEST(SanitizeDisplayName, FallsBackWhenNothingUsableRemains) {
  EXPECT_EQ(SanitizeDisplayName("", "photo-3"), "photo-3");
  EXPECT_EQ(SanitizeDisplayName("/", "photo-3"), "photo-3");
  EXPECT_EQ(SanitizeDisplayName("a/..", "photo-3"), "photo-3");
  EXPECT_EQ(SanitizeDisplayName("..", "photo-3"), "photo-3");
  EXPECT_EQ(SanitizeDisplayName(" \t ", "photo-3"), "photo-3");
  EXPECT_EQ(SanitizeDisplayName(std::string("\x01\x02", 2), "photo-3"), "photo-3");
}

TEST(SanitizeDisplayName, RemovesControlsAndBadUtf8) {
  EXPECT_EQ(SanitizeDisplayName("a\r\nb\x1b[31m.jpg", "x"), "ab[31m.jpg");
  EXPECT_EQ(SanitizeDisplayName(std::string("a\0b.jpg", 7), "x"), "ab.jpg");
  EXPECT_EQ(SanitizeDisplayName("caf\xc3\xa9.jpg", "x"), "caf\xc3\xa9.jpg");  // Valid UTF-8 kept.
  EXPECT_EQ(SanitizeDisplayName("bad\xff\xfe.jpg", "x"), "bad??.jpg");
  EXPECT_EQ(SanitizeDisplayName("over\xc0\xaflong", "x"), "over??long");  // Overlong '/'.
  EXPECT_EQ(SanitizeDisplayName("  spaced.jpg  ", "x"), "spaced.jpg");
}

// Issue 12: U+202E (right-to-left override) made "photo\u202Egpj.exe" display as
// "photoexe.jpg"; bidirectional and C1 controls are removed, other characters kept.
TEST(SanitizeDisplayName, RemovesBidirectionalAndC1Controls) {
  EXPECT_EQ(SanitizeDisplayName("photo\xE2\x80\xAEgpj.exe", "x"), "photogpj.exe");
  EXPECT_EQ(SanitizeDisplayName("\xE2\x80\xAA\xE2\x80\xAB\xE2\x80\xAC\xE2\x80\xAD"
                                "a"
                                "\xE2\x80\x8E\xE2\x80\x8F\xD8\x9C.jpg",
                                "x"),
            "a.jpg");
  EXPECT_EQ(SanitizeDisplayName("\xE2\x81\xA6"
                                "b\xE2\x81\xA7\xE2\x81\xA8\xE2\x81\xA9.jpg",
                                "x"),
            "b.jpg");
  EXPECT_EQ(SanitizeDisplayName("c\xC2\x85\xC2\x9F.jpg", "x"), "c.jpg");
  EXPECT_EQ(SanitizeDisplayName("\xE2\x80\xAE", "fallback"), "fallback");
  // Neighbours of the controls stay: U+2010 (hyphen), U+2070, U+00A0, Arabic letters.
  EXPECT_EQ(SanitizeDisplayName("a\xE2\x80\x90"
                                "b\xE2\x81\xB0\xC2\xA0\xD8\xA8.jpg",
                                "x"),
            "a\xE2\x80\x90"
            "b\xE2\x81\xB0\xC2\xA0\xD8\xA8.jpg");
}

TEST(SanitizeDisplayName, LimitsTheLengthAtACharacterBoundary) {
  std::string long_name;
  for (int i = 0; i < 150; ++i) long_name += "\xc3\xa9";  // 300 bytes of 'é'.
  const std::string clean = SanitizeDisplayName(long_name, "x");
  EXPECT_LE(clean.size(), kMaxDisplayNameBytes);
  EXPECT_EQ(clean.size() % 2, 0u);
  EXPECT_EQ(clean.substr(0, 2), "\xc3\xa9");
}

TEST(StoredPhotoName, NumbersFromOneWithFourDigits) {
  EXPECT_EQ(StoredPhotoName(0, "jpg"), "0001.jpg");
  EXPECT_EQ(StoredPhotoName(41, "png"), "0042.png");
  EXPECT_EQ(StoredPhotoName(9999, "tif"), "10000.tif");
}

TEST(CheckRelativePath, AcceptsPlainRelativePaths) {
  EXPECT_TRUE(CheckRelativePath("model.glb").ok());
  EXPECT_TRUE(CheckRelativePath("report/similarity.png").ok());
  EXPECT_TRUE(CheckRelativePath("photos/a..b.jpg").ok());
  EXPECT_TRUE(CheckRelativePath("photos/", /*allow_trailing_slash=*/true).ok());
}

TEST(CheckRelativePath, RefusesEscapes) {
  for (const char* name : {"../a.jpg", "a/../../b", "..", "/etc/passwd", "C:/x.jpg", "C:x.jpg",
                           "a\\..\\b", "a//b", "./a", "a/./b", "", "photos/"}) {
    SCOPED_TRACE(name);
    const Status status = CheckRelativePath(name);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  }
  EXPECT_FALSE(CheckRelativePath(std::string("a\0b", 3)).ok());
  EXPECT_FALSE(CheckRelativePath(std::string(2000, 'a')).ok());
  EXPECT_NE(CheckRelativePath("../a.jpg").message().find("'..'"), std::string::npos);
}

TEST(QuoteForMessage, EscapesQuotesAndControls) {
  EXPECT_EQ(QuoteForMessage("a.jpg"), "\"a.jpg\"");
  EXPECT_EQ(QuoteForMessage("a\"b\n"), "\"a\\\"b\\x0a\"");
  EXPECT_EQ(QuoteForMessage(std::string(400, 'x')).size(), 300u + 2 + 3);
}

}  // namespace
}  // namespace reconduit::server
