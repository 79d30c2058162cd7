#include "core/util/logging.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace reconduit {
namespace {

using ::testing::HasSubstr;

TEST(ThrowCheck, PassingCheckDoesNothing) {
  EXPECT_NO_THROW(THROW_CHECK(1 + 1 == 2));
  EXPECT_NO_THROW(THROW_CHECK_EQ(2, 2) << "never formatted");
  EXPECT_NO_THROW(THROW_CHECK_LT(1, 2));
}

TEST(ThrowCheck, FailingCheckThrowsWithExpressionAndContext) {
  try {
    const int n = 3;
    THROW_CHECK_EQ(n, 7) << "for image "
                         << "a.jpg";
    FAIL() << "expected a throw";
  } catch (const CheckError& e) {
    const std::string what = e.what();
    EXPECT_THAT(what, HasSubstr("Check failed: n == 7 (3 vs. 7)"));
    EXPECT_THAT(what, HasSubstr(": for image a.jpg"));
    EXPECT_THAT(what, HasSubstr("logging_test.cc"));
  }
}

TEST(ThrowCheck, NotNull) {
  int* p = nullptr;
  EXPECT_THROW(THROW_CHECK_NOTNULL(p), CheckError);
  int x = 0;
  p = &x;
  EXPECT_NO_THROW(THROW_CHECK_NOTNULL(p));
}

TEST(ThrowCheck, EvaluatesOperandsOnce) {
  int calls = 0;
  auto f = [&] { return ++calls; };
  THROW_CHECK_GE(f(), 1);
  EXPECT_EQ(calls, 1);
}

TEST(Logging, SinkReceivesLinesAtOrAboveLevel) {
  std::vector<std::pair<LogLevel, std::string>> lines;
  LogSink previous = SetLogSink(
      [&](LogLevel level, std::string_view m) { lines.emplace_back(level, std::string(m)); });
  SetMinLogLevel(LogLevel::kInfo);
  LOG_DEBUG << "hidden";
  LOG_INFO << "registered " << 11 << " images";
  LOG_ERROR << "oops";
  SetLogSink(previous);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0].first, LogLevel::kInfo);
  EXPECT_EQ(lines[0].second, "registered 11 images");
  EXPECT_EQ(lines[1].first, LogLevel::kError);
}

}  // namespace
}  // namespace reconduit
