// Ray-casting renderer for textured synthetic scenes: an image and its exact depth map as a
// given camera (with distortion) sees the scene.
//
// Each pixel casts n x n rays through a regular grid of points inside its square (pixel
// centres at integer coordinates, core/geometry/camera.h), undistorted by the camera model,
// and averages their colours (box-filter antialiasing). A ray that hits nothing, or a
// sample beyond the radius where the distortion folds back (Camera::Undistort fails), takes
// the scene's background colour. There is no lighting: pixels show the surfaces' albedo, so
// a rendered pixel can be compared with EvaluateTexture at the surface point it sees. Quads
// are intersected in closed form; height fields by IntersectHeightField (textured_scene.h),
// only up to the nearest quad hit, which makes a terrain view ~5x slower than a room view.
#ifndef RECONDUIT_CORE_SCENE_RENDER_H_
#define RECONDUIT_CORE_SCENE_RENDER_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/textured_scene.h"

#include <opencv2/core.hpp>

#include <string>

namespace reconduit {

struct RenderOptions {
  // Rays per pixel along each axis, [1, 8]; n² rays per pixel. 2 removes most aliasing at
  // 4x the cost of 1.
  int samples_per_axis = 2;
  // True: an 8-bit gray image (0.299 R + 0.587 G + 0.114 B of the averaged colour, as
  // cv::COLOR_BGR2GRAY); false: 8-bit BGR.
  bool grayscale = false;
  // Threads over image rows (see EffectiveNumThreads); the result does not depend on it.
  int num_threads = 0;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

struct RenderedView {
  // camera.height x camera.width, CV_8UC3 (BGR) or CV_8UC1 (grayscale).
  cv::Mat image;
  // camera.height x camera.width, CV_32FC1: depth in metres (z in the camera frame) of the
  // surface hit by the ray through the pixel centre; 0 where that ray hits nothing.
  cv::Mat depth;
};

// Renders `scene` seen by `camera` at pose `cam_from_world`. Throws CheckError when the
// camera, the scene or the options fail their Check(). Thread-safe; deterministic.
RenderedView RenderScene(const TexturedScene& scene,
                         const Camera& camera,
                         const Rigid3d& cam_from_world,
                         const RenderOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_RENDER_H_
