#include "core/optim/ransac_options.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace reconduit {
namespace {

TEST(RANSACOptions, DefaultsAreValid) {
  std::string error = "unchanged";
  EXPECT_TRUE(RANSACOptions().Check(&error)) << error;
  EXPECT_TRUE(error.empty());
  EXPECT_TRUE(RANSACOptions().Check(nullptr));
}

TEST(RANSACOptions, EachInvalidFieldIsNamed) {
  const auto expect_invalid = [](const RANSACOptions& options, const std::string& field) {
    std::string error;
    EXPECT_FALSE(options.Check(&error)) << field;
    EXPECT_NE(error.find(field), std::string::npos) << error;
  };
  RANSACOptions o;
  o.max_error = 0.0;
  expect_invalid(o, "max_error");
  o = RANSACOptions();
  o.max_error = std::numeric_limits<double>::quiet_NaN();
  expect_invalid(o, "max_error");
  o = RANSACOptions();
  o.min_inlier_ratio = 1.5;
  expect_invalid(o, "min_inlier_ratio");
  o = RANSACOptions();
  o.confidence = 1.0;
  expect_invalid(o, "confidence");
  o = RANSACOptions();
  o.dyn_num_trials_multiplier = 0.5;
  expect_invalid(o, "dyn_num_trials_multiplier");
  o = RANSACOptions();
  o.min_num_trials = 20;
  o.max_num_trials = 10;
  expect_invalid(o, "max_num_trials");
  o = RANSACOptions();
  o.max_local_iterations = 0;
  expect_invalid(o, "max_local_iterations");
  o = RANSACOptions();
  o.num_local_trials = -1;
  expect_invalid(o, "num_local_trials");
}

TEST(ComputeRANSACNumTrials, MatchesTheClosedForm) {
  // w = 0.5, s = 2, p = 0.99: log(0.01) / log(0.75) = 16.008 -> 17.
  EXPECT_EQ(ComputeRANSACNumTrials(50, 100, 2, 0.99, 1.0), 17u);
  // Multiplier 3: ceil(48.02) = 49.
  EXPECT_EQ(ComputeRANSACNumTrials(50, 100, 2, 0.99, 3.0), 49u);
  // w = 0.5, s = 7, p = 0.999: log(0.001) / log(1 - 1/128) = 880.7 -> 881.
  EXPECT_EQ(ComputeRANSACNumTrials(500, 1000, 7, 0.999, 1.0), 881u);
  EXPECT_EQ(ComputeRANSACNumTrials(100, 100, 7, 0.999, 3.0), 1u);
  EXPECT_EQ(ComputeRANSACNumTrials(0, 100, 7, 0.999, 1.0), std::numeric_limits<std::size_t>::max());
  // A tiny inlier ratio saturates instead of overflowing.
  EXPECT_EQ(ComputeRANSACNumTrials(1, 1000000000, 8, 0.999, 3.0),
            std::numeric_limits<std::size_t>::max());
}

}  // namespace
}  // namespace reconduit
