#include "core/util/cancel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace reconduit {
namespace {

TEST(CancelToken, CopiesShareTheFlag) {
  CancelToken token;
  const CancelToken copy = token;
  EXPECT_FALSE(copy.IsCanceled());
  EXPECT_NO_THROW(copy.ThrowIfCanceled());
  token.RequestCancel();
  EXPECT_TRUE(copy.IsCanceled());
  EXPECT_THROW(copy.ThrowIfCanceled(), CanceledError);
}

TEST(CancelToken, ProbeIsThrottled) {
  CancelToken token;
  std::atomic<int> calls{0};
  token.SetProbe([&] { return ++calls >= 3; }, std::chrono::hours(1));
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(token.IsCanceled());
  EXPECT_EQ(calls.load(), 1) << "the probe runs once per interval";
}

TEST(CancelToken, ProbeCanCancel) {
  CancelToken token;
  std::atomic<int> calls{0};
  token.SetProbe([&] { return ++calls >= 3; }, std::chrono::milliseconds(0));
  EXPECT_FALSE(token.IsCanceled());
  EXPECT_FALSE(token.IsCanceled());
  EXPECT_TRUE(token.IsCanceled());
  EXPECT_TRUE(token.IsCanceled()) << "cancellation sticks";
  EXPECT_EQ(calls.load(), 3);
}

TEST(CancelToken, CancelFromAnotherThread) {
  CancelToken token;
  std::thread t([token] { token.RequestCancel(); });
  t.join();
  EXPECT_TRUE(token.IsCanceled());
}

}  // namespace
}  // namespace reconduit
