#include "core/sfm/initial_calibration.h"

#include "core/util/logging.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

// The upper median (the middle element, or the higher of the two middle ones).
double MedianOf(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The fundamental matrices with enough inliers for self-calibration.
std::vector<Eigen::Matrix3d> SelfCalibrationPairs(const InitialCalibrationInput& input,
                                                  int min_inliers) {
  std::vector<Eigen::Matrix3d> fundamentals;
  for (const CameraPairFundamental& pair : input.fundamentals) {
    if (pair.num_inliers >= min_inliers) fundamentals.push_back(pair.F);
  }
  return fundamentals;
}

}  // namespace

std::string_view InitialFocalSourceName(InitialFocalSource source) {
  switch (source) {
    case InitialFocalSource::kExif:
      return "exif";
    case InitialFocalSource::kSelfCalibration:
      return "self_calibration";
    case InitialFocalSource::kDefault:
      return "default";
  }
  return "default";
}

bool InitialCalibrationOptions::Check(std::string* error) const {
  std::ostringstream m;
  std::string self_error;
  if (min_self_calibration_inliers < 0) {
    m << "min_self_calibration_inliers must be at least 0, got " << min_self_calibration_inliers;
  } else if (!(focal_disagreement > 0.0)) {
    m << "focal_disagreement must be > 0, got " << focal_disagreement;
  } else if (!(default_focal_factor > 0.0 && std::isfinite(default_focal_factor))) {
    m << "default_focal_factor must be > 0, got " << default_focal_factor;
  } else if (!self_calibration.Check(&self_error)) {
    m << "self_calibration: " << self_error;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

InitialCalibration EstimateInitialCalibration(const InitialCalibrationInput& input,
                                              const InitialCalibrationOptions& options) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK(input.width > 0 && input.height > 0);
  InitialCalibration result;
  result.camera =
      Camera::FromFocal(input.width, input.height,
                        options.default_focal_factor * std::max(input.width, input.height));
  const std::vector<Eigen::Matrix3d> fundamentals =
      SelfCalibrationPairs(input, options.min_self_calibration_inliers);
  result.num_pairs = static_cast<int>(fundamentals.size());
  const Result<SharedFocalEstimate> self = EstimateSharedFocal(
      fundamentals, result.camera.cx, result.camera.cy,
      DefaultFocalRange(result.camera.width, result.camera.height), options.self_calibration);
  if (self.ok()) {
    result.self_calibration = *self;
  } else {
    result.self_calibration_error = self.status().message();
  }
  if (!input.exif_focals.empty()) result.exif_focal = MedianOf(input.exif_focals);

  if (options.use_exif && result.exif_focal) {
    result.camera.focal = *result.exif_focal;
    result.source = InitialFocalSource::kExif;
    if (result.self_calibration && std::abs(result.self_calibration->focal / result.camera.focal -
                                            1.0) > options.focal_disagreement) {
      std::ostringstream m;
      m << "EXIF focal length and self-calibration disagree by more than "
        << std::lround(100.0 * options.focal_disagreement) << " %";
      result.warning = m.str();
    }
  } else if (result.self_calibration) {
    result.camera.focal = result.self_calibration->focal;
    result.source = InitialFocalSource::kSelfCalibration;
  } else {
    result.source = InitialFocalSource::kDefault;
    std::ostringstream m;
    m << "no EXIF focal length and self-calibration from photo pairs was not possible; the "
         "focal length was searched with trial reconstructions from "
      << options.default_focal_factor << " x the longer side";
    result.warning = m.str();
  }
  return result;
}

}  // namespace reconduit
