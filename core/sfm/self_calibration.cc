#include "core/sfm/self_calibration.h"

#include "core/util/logging.h"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

constexpr int kScanSteps = 120;
constexpr double kGolden = 0.6180339887498949;

// Golden-section minimisation of g over [a, b] (g unimodal there).
template <typename Function>
double GoldenSection(const Function& g, double a, double b, int iterations = 60) {
  double c = b - kGolden * (b - a);
  double d = a + kGolden * (b - a);
  double gc = g(c), gd = g(d);
  for (int i = 0; i < iterations; ++i) {
    if (gc < gd) {
      b = d;
      d = c;
      gd = gc;
      c = b - kGolden * (b - a);
      gc = g(c);
    } else {
      a = c;
      c = d;
      gc = gd;
      d = a + kGolden * (b - a);
      gd = g(d);
    }
  }
  return 0.5 * (a + b);
}

// Log-spaced grid over the range.
std::vector<double> LogGrid(const FocalSearchRange& range, int steps) {
  std::vector<double> grid(steps);
  const double a = std::log(range.min_focal), b = std::log(range.max_focal);
  for (int i = 0; i < steps; ++i) grid[i] = std::exp(a + (b - a) * i / (steps - 1));
  return grid;
}

}  // namespace

FocalSearchRange DefaultFocalRange(int width, int height) {
  const double side = std::max(width, height);
  return {0.3 * side, 8.0 * side};
}

double EssentialCost(const Eigen::Matrix3d& fundamental, double focal, double cx, double cy) {
  Eigen::Matrix3d k;
  k << focal, 0, cx, 0, focal, cy, 0, 0, 1;
  const Eigen::Matrix3d e = k.transpose() * fundamental * k;
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::Matrix3d>(e).singularValues();
  if (s(0) + s(1) <= 0.0) return 1.0;
  return (s(0) - s(1)) / (s(0) + s(1));
}

std::optional<PairFocalEstimate> EstimateFocalFromFundamental(const Eigen::Matrix3d& fundamental,
                                                              double cx,
                                                              double cy,
                                                              const FocalSearchRange& range) {
  THROW_CHECK(range.min_focal > 0.0 && range.max_focal > range.min_focal);
  const std::vector<double> grid = LogGrid(range, kScanSteps);
  std::vector<double> cost(grid.size());
  for (std::size_t i = 0; i < grid.size(); ++i)
    cost[i] = EssentialCost(fundamental, grid[i], cx, cy);
  const std::size_t best = std::min_element(cost.begin(), cost.end()) - cost.begin();
  if (best == 0 || best + 1 == grid.size()) return std::nullopt;

  auto g = [&](double log_f) { return EssentialCost(fundamental, std::exp(log_f), cx, cy); };
  const double log_f = GoldenSection(g, std::log(grid[best - 1]), std::log(grid[best + 1]));
  PairFocalEstimate estimate;
  estimate.focal = std::exp(log_f);
  estimate.cost = g(log_f);
  estimate.sharpness = std::min(g(log_f + std::log(1.3)), g(log_f - std::log(1.3))) - estimate.cost;
  return estimate;
}

bool SharedFocalOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (!(min_sharpness >= 0.0 && min_sharpness <= 1.0)) {
    m << "min_sharpness must be in [0, 1], got " << min_sharpness;
  } else if (!(max_cost >= 0.0 && max_cost <= 1.0)) {
    m << "max_cost must be in [0, 1], got " << max_cost;
  } else if (!(agreement > 0.0 && agreement <= 1.0)) {
    m << "agreement must be in (0, 1], got " << agreement;
  } else if (min_agreeing_pairs < 1) {
    m << "min_agreeing_pairs must be at least 1, got " << min_agreeing_pairs;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

Result<SharedFocalEstimate> EstimateSharedFocal(const std::vector<Eigen::Matrix3d>& fundamentals,
                                                double cx,
                                                double cy,
                                                const FocalSearchRange& range,
                                                const SharedFocalOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  SharedFocalEstimate result;
  result.num_pairs = static_cast<int>(fundamentals.size());

  struct Usable {
    double log_f;
    double weight;
    const Eigen::Matrix3d* f;
  };
  std::vector<Usable> usable;
  for (const Eigen::Matrix3d& f : fundamentals) {
    const auto estimate = EstimateFocalFromFundamental(f, cx, cy, range);
    if (!estimate || estimate->sharpness < options.min_sharpness ||
        estimate->cost > options.max_cost) {
      continue;
    }
    usable.push_back({std::log(estimate->focal), estimate->sharpness, &f});
  }
  result.num_usable = static_cast<int>(usable.size());
  if (result.num_usable < options.min_agreeing_pairs) {
    return Status::Degenerate("self-calibration: only " + std::to_string(usable.size()) + " of " +
                              std::to_string(fundamentals.size()) +
                              " photo pairs constrain the focal length");
  }

  // Mode of the estimates: a Gaussian kernel density vote in log f, weighted by sharpness.
  const double bandwidth = std::log1p(options.agreement) / 2.0;
  double best_density = -1.0, mode = usable.front().log_f;
  for (const Usable& candidate : usable) {
    double density = 0.0;
    for (const Usable& other : usable) {
      const double z = (candidate.log_f - other.log_f) / bandwidth;
      density += other.weight * std::exp(-0.5 * z * z);
    }
    if (density > best_density) {
      best_density = density;
      mode = candidate.log_f;
    }
  }

  // Refine: minimise the summed cost of the pairs that agree with the mode.
  std::vector<const Usable*> agreeing;
  for (const Usable& u : usable) {
    if (std::abs(u.log_f - mode) <= std::log1p(options.agreement)) agreeing.push_back(&u);
  }
  result.num_agreeing = static_cast<int>(agreeing.size());
  if (result.num_agreeing < options.min_agreeing_pairs) {
    return Status::Degenerate("self-calibration: the photo pairs disagree on the focal length (" +
                              std::to_string(agreeing.size()) + " of " +
                              std::to_string(usable.size()) + " agree)");
  }
  auto total = [&](double log_f) {
    double sum = 0.0;
    for (const Usable* u : agreeing) sum += EssentialCost(*u->f, std::exp(log_f), cx, cy);
    return sum;
  };
  const double window = std::log1p(options.agreement);
  const double log_f = GoldenSection(total, mode - window, mode + window);
  result.focal = std::exp(log_f);

  std::vector<double> deviations;
  for (const Usable* u : agreeing)
    deviations.push_back(std::abs(std::exp(u->log_f) / result.focal - 1.0));
  std::nth_element(deviations.begin(), deviations.begin() + deviations.size() / 2,
                   deviations.end());
  result.spread = deviations[deviations.size() / 2];
  return result;
}

}  // namespace reconduit
