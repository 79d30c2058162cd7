#include "core/estimators/two_view_geometry.h"

#include "core/estimators/gric.h"
#include "core/estimators/solvers/fundamental_matrix.h"
#include "core/estimators/solvers/homography_matrix.h"
#include "core/optim/loransac.h"
#include "core/optim/support_measurement.h"
#include "core/util/logging.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

using FundamentalRANSAC = LORANSAC<FundamentalMatrixSevenPointEstimator,
                                   FundamentalMatrixEightPointEstimator,
                                   MEstimatorSupportMeasurer>;
using HomographyRANSAC =
    LORANSAC<HomographyMatrixEstimator, HomographyMatrixEstimator, MEstimatorSupportMeasurer>;

constexpr double kMinGricSigma = 0.1;  // pixels; SIFT keypoints are rarely better than this.
// Above this ratio of H inliers to F inliers, sigma is estimated from H (see below).
constexpr double kSigmaFromHRatio = 0.9;
constexpr std::size_t kMinNumMatches = FundamentalMatrixSevenPointEstimator::kMinNumSamples;

// Standard deviation of the points along their least-spread direction (0 for collinear or
// coincident points), in the points' units.
double MinorAxisStdDev(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  for (const auto& p : points) covariance += (p - mean) * (p - mean).transpose();
  covariance /= static_cast<double>(points.size());
  if (!covariance.allFinite()) return 0.0;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(covariance, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(solver.eigenvalues()(0), 0.0));
}

double Median(std::vector<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// Robust noise estimate from the squared residuals of inliers of a model whose residual has
// `codim` degrees of freedom (1 for the Sampson error of F, 2 for that of H).
double EstimateSigma(const std::vector<double>& squared_residuals,
                     const std::vector<char>& inlier_mask,
                     int codim) {
  std::vector<double> inlier_residuals;
  for (std::size_t i = 0; i < squared_residuals.size(); ++i) {
    if (inlier_mask[i]) inlier_residuals.push_back(squared_residuals[i]);
  }
  if (inlier_residuals.empty()) return kMinGricSigma;
  // Medians of chi-square with 1 and 2 degrees of freedom: 0.4549 and 2 ln 2.
  const double chi2_median = codim == 1 ? 0.454936 : 2.0 * std::log(2.0);
  return std::max(kMinGricSigma, std::sqrt(Median(inlier_residuals) / chi2_median));
}

TwoViewGeometryReport Degenerate(TwoViewGeometryReport report, std::string message) {
  report.success = false;
  report.type = TwoViewModelType::kDegenerate;
  report.message = std::move(message);
  return report;
}

}  // namespace

std::string_view TwoViewModelTypeName(TwoViewModelType type) {
  switch (type) {
    case TwoViewModelType::kUndefined:
      return "undefined";
    case TwoViewModelType::kDegenerate:
      return "degenerate";
    case TwoViewModelType::kFundamental:
      return "fundamental";
    case TwoViewModelType::kHomography:
      return "homography";
  }
  return "unknown";
}

bool TwoViewGeometryOptions::Check(std::string* error) const {
  std::string ransac_error;
  if (!ransac.Check(&ransac_error)) {
    if (error != nullptr) *error = "TwoViewGeometryOptions.ransac: " + ransac_error;
    return false;
  }
  std::ostringstream s;
  if (!(homography_max_error > 0.0) || !std::isfinite(homography_max_error)) {
    s << "homography_max_error must be a finite number > 0, got " << homography_max_error;
  } else if (min_num_inliers < static_cast<int>(kMinNumMatches)) {
    s << "min_num_inliers must be >= " << kMinNumMatches << ", got " << min_num_inliers;
  } else if (!std::isfinite(gric_sigma)) {
    s << "gric_sigma must be finite (<= 0 means estimate), got " << gric_sigma;
  }
  if (!s.str().empty()) {
    if (error != nullptr) *error = "TwoViewGeometryOptions: " + s.str();
    return false;
  }
  if (error != nullptr) error->clear();
  return true;
}

const std::vector<char>& TwoViewGeometryReport::inlier_mask() const {
  static const std::vector<char> kEmpty;
  if (type == TwoViewModelType::kFundamental) return inlier_mask_F;
  if (type == TwoViewModelType::kHomography) return inlier_mask_H;
  return kEmpty;
}

TwoViewGeometryReport EstimateTwoViewGeometry(const std::vector<Eigen::Vector2d>& points1,
                                              const std::vector<Eigen::Vector2d>& points2,
                                              const TwoViewGeometryOptions& options,
                                              const CancelToken* cancel) {
  THROW_CHECK_EQ(points1.size(), points2.size());
  std::string options_error;
  THROW_CHECK(options.Check(&options_error)) << options_error;

  TwoViewGeometryReport report;
  const std::size_t num_matches = points1.size();
  if (num_matches < kMinNumMatches) {
    return Degenerate(std::move(report), "need at least " + std::to_string(kMinNumMatches) +
                                             " matches, got " + std::to_string(num_matches));
  }
  // Whole-set degeneracy, which RANSAC cannot see: a model fitted to points that all lie on
  // one line (or at one place) in an image can have every match as an inlier and still be
  // meaningless.
  for (int image = 0; image < 2; ++image) {
    const double spread = MinorAxisStdDev(image == 0 ? points1 : points2);
    if (!(spread > options.ransac.max_error)) {
      std::ostringstream s;
      s << "points in image " << image + 1 << " are collinear or coincident (spread across "
        << "their main direction " << spread << " px <= max_error " << options.ransac.max_error
        << " px)";
      return Degenerate(std::move(report), s.str());
    }
  }

  // Fundamental matrix.
  const auto f_report = FundamentalRANSAC(options.ransac).Estimate(points1, points2, cancel);
  report.num_trials_F = f_report.num_trials;
  if (f_report.canceled) {
    report.canceled = true;
    report.message = "canceled";
    return report;
  }
  const bool f_ok = f_report.success && f_report.support.num_inliers >=
                                            static_cast<std::size_t>(options.min_num_inliers);
  if (f_report.success) {
    report.F = f_report.model;
    report.inlier_mask_F = f_report.inlier_mask;
    report.num_inliers_F = f_report.support.num_inliers;
  }

  // Homography, with the same trial settings and seed.
  RANSACOptions h_options = options.ransac;
  h_options.max_error = options.homography_max_error;
  const auto h_report = HomographyRANSAC(h_options).Estimate(points1, points2, cancel);
  report.num_trials_H = h_report.num_trials;
  if (h_report.canceled) {
    report.canceled = true;
    report.message = "canceled";
    return report;
  }
  const bool h_ok = h_report.success && h_report.support.num_inliers >=
                                            static_cast<std::size_t>(options.min_num_inliers);
  if (h_report.success) {
    report.H = h_report.model;
    report.inlier_mask_H = h_report.inlier_mask;
    report.num_inliers_H = h_report.support.num_inliers;
  }

  if (!f_ok && !h_ok) {
    std::ostringstream s;
    s << "too few inliers: F " << report.num_inliers_F << ", H " << report.num_inliers_H
      << " (need " << options.min_num_inliers << ")";
    return Degenerate(std::move(report), s.str());
  }

  // GRIC over the matches that either model explains. Torr scores all n matches, with
  // outliers paying the cap; but the cap is lambda3 * (r - d), 2 for F and 4 for H, so
  // mismatches would push every pair with many of them towards F. Scoring the union of both
  // inlier sets keeps the comparison about the geometry of the matches that are real.
  std::vector<double> residuals_F, residuals_H;
  if (f_ok) ComputeSquaredSampsonError(points1, points2, report.F, &residuals_F);
  if (h_ok) ComputeHomographySquaredSampsonError(points1, points2, report.H, &residuals_H);
  if (options.gric_sigma > 0.0) {
    report.gric_sigma = options.gric_sigma;
  } else if (f_ok && !(h_ok && report.num_inliers_H >= kSigmaFromHRatio * report.num_inliers_F)) {
    report.gric_sigma = EstimateSigma(residuals_F, report.inlier_mask_F, /*codim=*/1);
  } else {
    // H explains (nearly) every F inlier: the data are (nearly) degenerate for F, whose
    // extra freedom then fits part of the noise and makes its residuals underestimate sigma.
    // H is well determined there, so its residuals give the estimate.
    report.gric_sigma = EstimateSigma(residuals_H, report.inlier_mask_H, /*codim=*/2);
  }
  std::vector<double> union_F, union_H;
  for (std::size_t i = 0; i < num_matches; ++i) {
    const bool in_F = f_ok && report.inlier_mask_F[i];
    const bool in_H = h_ok && report.inlier_mask_H[i];
    if (!in_F && !in_H) continue;
    if (f_ok) union_F.push_back(residuals_F[i]);
    if (h_ok) union_H.push_back(residuals_H[i]);
  }
  report.num_gric_matches = f_ok ? union_F.size() : union_H.size();
  if (f_ok) {
    report.gric_F = ComputeGRIC(union_F, report.gric_sigma, kGricDataDim, kGricFundamentalDim,
                                kGricFundamentalParams);
  }
  if (h_ok) {
    report.gric_H = ComputeGRIC(union_H, report.gric_sigma, kGricDataDim, kGricHomographyDim,
                                kGricHomographyParams);
  }

  report.success = true;
  report.message.clear();
  report.type = h_ok && report.gric_H <= report.gric_F ? TwoViewModelType::kHomography
                                                       : TwoViewModelType::kFundamental;
  return report;
}

}  // namespace reconduit
