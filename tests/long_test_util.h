// Helpers for the cross-module tests that have a long variant (ctest label `long`): the long
// entry sets RECONDUIT_LONG_TESTS=1, the regular run skips those tests; counts and seeds come
// from the environment so that a run can be repeated or shortened.
#ifndef RECONDUIT_TESTS_LONG_TEST_UTIL_H_
#define RECONDUIT_TESTS_LONG_TEST_UTIL_H_

#include <cstdlib>
#include <string>

namespace reconduit::testing_util {

// True when run from a `long` ctest entry (RECONDUIT_LONG_TESTS=1).
inline bool LongTestsEnabled() {
  const char* value = std::getenv("RECONDUIT_LONG_TESTS");
  return value != nullptr && std::string(value) == "1";
}

// The integer in environment variable `name`, or `fallback` when it is not set.
inline long EnvLong(const char* name, long fallback) {
  const char* value = std::getenv(name);
  return value != nullptr ? std::stol(value) : fallback;
}

}  // namespace reconduit::testing_util

#endif  // RECONDUIT_TESTS_LONG_TEST_UTIL_H_
