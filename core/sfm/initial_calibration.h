// The initial calibration of one camera (the photos that share intrinsics), before
// reconstruction: which focal length the mapper starts from, where it comes from, and whether
// it is only a guess.
//
// The policy, in order:
//  - With use_exif and at least one photo with an EXIF focal length: the median of those
//    (EXIF is usually within a few percent). A self-calibration that disagrees by more than
//    `focal_disagreement` is reported as a warning, but EXIF still wins: bundle adjustment
//    refines the focal either way, and EXIF is wrong far less often than self-calibration.
//  - Otherwise, self-calibration from the fundamental matrices of the camera's photo pairs
//    (core/sfm/self_calibration.h), using the pairs with at least
//    `min_self_calibration_inliers` inliers.
//  - Otherwise `default_focal_factor` x the longer side (1.2: a common phone/compact field of
//    view), with a warning. Such a focal is "uncertain": the mapper searches for it with small
//    trial reconstructions first (MapperInput::uncertain_focal_camera_ids).
// The principal point is the image centre and the distortion zero in every case.
#ifndef RECONDUIT_CORE_SFM_INITIAL_CALIBRATION_H_
#define RECONDUIT_CORE_SFM_INITIAL_CALIBRATION_H_

#include "core/geometry/camera.h"
#include "core/sfm/self_calibration.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace reconduit {

struct InitialCalibrationOptions {
  // Prefer the photos' EXIF focal length when there is one (the pipeline option use_exif).
  bool use_exif = true;
  // A pair's fundamental matrix takes part in self-calibration from this many inliers. [0, ...]
  int min_self_calibration_inliers = 50;
  // EXIF and self-calibration "disagree" beyond this relative difference. (0, ...)
  double focal_disagreement = 0.15;
  // The focal length with neither EXIF nor self-calibration, as a multiple of the longer
  // side. (0, ...)
  double default_focal_factor = 1.2;
  SharedFocalOptions self_calibration;

  bool Check(std::string* error) const;
};

// A fundamental matrix between two photos of the camera (x2ᵀ F x1 = 0, pixels).
struct CameraPairFundamental {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  int num_inliers = 0;
};

// What is known about one camera before reconstruction.
struct InitialCalibrationInput {
  int width = 0;   // Pixels, > 0.
  int height = 0;  // Pixels, > 0.
  // The EXIF focal lengths (pixels) of the camera's photos that have one.
  std::vector<double> exif_focals;
  // The fundamental matrices of pairs of the camera's photos (pairs with a homography only
  // are not given).
  std::vector<CameraPairFundamental> fundamentals;
};

enum class InitialFocalSource { kExif, kSelfCalibration, kDefault };
// "exif", "self_calibration", "default" (as in work/sparse/calibration.json).
std::string_view InitialFocalSourceName(InitialFocalSource source);

struct InitialCalibration {
  // Camera::FromFocal(width, height, initial focal): centred principal point, no distortion.
  Camera camera;
  InitialFocalSource source = InitialFocalSource::kDefault;
  // The fundamental matrices used for self-calibration (enough inliers).
  int num_pairs = 0;
  // The median EXIF focal (pixels), whether or not it was used; nullopt without EXIF.
  std::optional<double> exif_focal;
  // The self-calibration result, or why there is none (self_calibration_error).
  std::optional<SharedFocalEstimate> self_calibration;
  std::string self_calibration_error;
  // For the person reading the results (EXIF and self-calibration disagree, or the focal is a
  // guess); empty when there is nothing to say.
  std::string warning;

  // The focal is a guess that the mapper should search for first.
  bool UncertainFocal() const { return source == InitialFocalSource::kDefault; }
};

// The initial calibration of one camera by the policy above. Throws on invalid options or a
// non-positive size.
InitialCalibration EstimateInitialCalibration(const InitialCalibrationInput& input,
                                              const InitialCalibrationOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_INITIAL_CALIBRATION_H_
