// Photos as dense matching reads them: at the working resolution, without lens distortion.
//
// PatchMatch maps windows between photos by plane-induced homographies, which hold only for
// pinhole cameras, so every photo is resampled once to the pinhole camera with the same focal
// length and principal point (scaled to the working size) and no distortion. Downscaling
// averages the original pixels (INTER_AREA) before the resampling, so a half- or quarter-size
// working image is not aliased.
#ifndef RECONDUIT_CORE_MVS_MVS_VIEW_H_
#define RECONDUIT_CORE_MVS_MVS_VIEW_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"

#include <opencv2/core.hpp>

namespace reconduit {

// A photo prepared for dense matching.
struct MvsView {
  // CV_32FC1 grey levels (0-255 from PrepareView; NCC does not care about the scale),
  // camera.height x camera.width.
  cv::Mat gray;
  // Pinhole camera at this image's resolution; k1 and k2 are 0 (undistorted image).
  Camera camera;
  Rigid3d cam_from_world;
};

struct PreparedView {
  MvsView view;
  // CV_8UC3 BGR, the same pixels as view.gray, for the colours of fused points.
  cv::Mat color;
  // CV_8UC1: 255 where the undistorted pixel comes from inside the photo, 0 where it fell
  // outside (corners of strongly distorted photos).
  cv::Mat valid;
};

// The working size and camera of a photo of `camera` scaled so that its long side is at most
// `max_side` (unchanged when it fits or max_side <= 0): width and height rounded to whole
// pixels, focal and principal point scaled by width' / width, distortion removed.
Camera WorkingCamera(const Camera& camera, int max_side);

// Resamples `bgr` (CV_8UC3, the size of `camera`) to WorkingCamera(camera, max_side). Throws
// CheckError when the image does not match the camera.
PreparedView PrepareView(const cv::Mat& bgr,
                         const Camera& camera,
                         const Rigid3d& cam_from_world,
                         int max_side);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_MVS_VIEW_H_
