#include "core/estimators/gric.h"

#include "core/util/logging.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace reconduit {
namespace {

TEST(ComputeGRIC, MatchesTorrsFormulaByHand) {
  // n = 3, sigma = 2, r = 4, d = 3, k = 7: cap = 2 * (4 - 3) = 2.
  // rho: 4/4 = 1, 16/4 = 4 -> 2 (capped), 0 -> 0; sum = 3.
  // + log(4) * 3 * 3 + log(12) * 7.
  const double expected = 3.0 + std::log(4.0) * 9.0 + std::log(12.0) * 7.0;
  EXPECT_NEAR(ComputeGRIC({4.0, 16.0, 0.0}, 2.0, 4, 3, 7), expected, 1e-12);
  // The same residuals under an H-like model: cap 4, so 16/4 = 4 is not capped.
  const double expected_h = 5.0 + std::log(4.0) * 6.0 + std::log(12.0) * 8.0;
  EXPECT_NEAR(ComputeGRIC({4.0, 16.0, 0.0}, 2.0, 4, 2, 8), expected_h, 1e-12);
}

TEST(ComputeGRIC, NonFiniteResidualsPayTheCap) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_DOUBLE_EQ(ComputeGRIC({inf}, 1.0, 4, 2, 0), ComputeGRIC({1e9}, 1.0, 4, 2, 0));
  EXPECT_DOUBLE_EQ(ComputeGRIC({std::nan("")}, 1.0, 4, 2, 0), 4.0 + 2.0 * std::log(4.0));
}

TEST(ComputeGRIC, PrefersTheSimplerModelWhenBothFitEquallyWell) {
  // Equal residuals: H (d = 2) beats F (d = 3) by n * log(4) minus log(4n).
  const std::vector<double> residuals(100, 0.5);
  EXPECT_LT(ComputeGRIC(residuals, 1.0, 4, 2, 8), ComputeGRIC(residuals, 1.0, 4, 3, 7));
}

TEST(ComputeGRIC, InvalidArgumentsThrow) {
  EXPECT_THROW(ComputeGRIC({1.0}, 0.0, 4, 3, 7), CheckError);
  EXPECT_THROW(ComputeGRIC({1.0}, 1.0, 3, 3, 7), CheckError);
}

}  // namespace
}  // namespace reconduit
