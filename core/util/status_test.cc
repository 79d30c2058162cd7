#include "core/util/status.h"

#include <gtest/gtest.h>

#include <string>

namespace reconduit {
namespace {

TEST(Status, DefaultIsNotRunAndNotOk) {
  Status s;
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kNotRun);
}

TEST(Status, ToStringNamesCodeAndMessage) {
  EXPECT_EQ(Status::Ok().ToString(), "OK");
  EXPECT_EQ(Status::InvalidArgument("not an image").ToString(), "INVALID_ARGUMENT: not an image");
  EXPECT_EQ(Status::Canceled().code(), StatusCode::kCanceled);
}

TEST(Result, HoldsValueOrError) {
  Result<int> good(5);
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 5);
  Result<std::string> bad(Status::NotFound("no such file"));
  EXPECT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(), "no such file");
  EXPECT_THROW((void)bad.value(), CheckError);
}

TEST(Result, RejectsOkStatusWithoutValue) { EXPECT_THROW(Result<int>(Status::Ok()), CheckError); }

}  // namespace
}  // namespace reconduit
