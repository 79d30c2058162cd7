// Test-only: a toy line-fitting kernel for the robust estimators in core/optim, in the spirit
// of OpenMVG's robust_estimator_lineKernel_test.hpp. Models are lines y = slope * x + offset;
// residuals are squared vertical distances.
#ifndef RECONDUIT_CORE_OPTIM_LINE_ESTIMATOR_TEST_UTIL_H_
#define RECONDUIT_CORE_OPTIM_LINE_ESTIMATOR_TEST_UTIL_H_

#include <cmath>
#include <vector>

namespace reconduit {
namespace testing_util {

struct Line {
  double slope = 0.0;
  double offset = 0.0;
};

// Fits a line to 2 or more points by least squares; no model when all x are equal.
struct LineEstimator {
  using X_t = double;
  using Y_t = double;
  using M_t = Line;
  static constexpr int kMinNumSamples = 2;

  static void Estimate(const std::vector<double>& x,
                       const std::vector<double>& y,
                       std::vector<Line>* models) {
    models->clear();
    const double n = static_cast<double>(x.size());
    double sx = 0, sy = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      sx += x[i];
      sy += y[i];
    }
    const double mx = sx / n, my = sy / n;
    double sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      sxx += (x[i] - mx) * (x[i] - mx);
      sxy += (x[i] - mx) * (y[i] - my);
    }
    if (!(sxx > 1e-12)) return;  // Vertical or coincident points: degenerate.
    const double slope = sxy / sxx;
    models->push_back({slope, my - slope * mx});
  }

  static void Residuals(const std::vector<double>& x,
                        const std::vector<double>& y,
                        const Line& line,
                        std::vector<double>* residuals) {
    residuals->resize(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double r = y[i] - (line.slope * x[i] + line.offset);
      (*residuals)[i] = r * r;
    }
  }
};

// The same kernel used as a non-minimal local estimator, with a Refine step that counts its
// calls (so tests can see that LO-RANSAC detects and uses it).
struct RefiningLineEstimator : LineEstimator {
  static constexpr int kMinNumSamples = 3;
  static inline int num_refine_calls = 0;
  static void Refine(const std::vector<double>& x, const std::vector<double>& y, Line* line) {
    ++num_refine_calls;
    std::vector<Line> models;
    Estimate(x, y, &models);
    if (!models.empty()) *line = models[0];
  }
};

}  // namespace testing_util
}  // namespace reconduit

#endif  // RECONDUIT_CORE_OPTIM_LINE_ESTIMATOR_TEST_UTIL_H_
