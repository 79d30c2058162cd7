// Bundler v0.3 export: bundle.out and list.txt, as described in the Bundler user's manual
// ("Output format and scene representation").
//
// list.txt holds one image name per line (RegisteredImage::name as is). bundle.out holds
//   # Bundle file v0.3
//   <num_cameras> <num_points>
//   per camera:  f k1 k2 / R (three rows) / t
//   per point:   x y z / r g b / n then n times: camera key x y
// Cameras are the registered images in increasing image id, and camera i of bundle.out is
// line i of list.txt (both 0-based). Only registered images are written: Bundler's
// placeholder cameras for unregistered photos (all zeros) are not emitted. `key` is the
// keypoint index in RegisteredImage::keypoints.
//
// Camera model and conversion. Bundler projects a world point X with
//   P = R X + t,   p = -P / P.z,   p' = f r(p) p,   r(p) = 1 + k1 |p|² + k2 |p|⁴,
// where p' is in pixels from the IMAGE CENTRE with x to the right and y UP, and the camera
// looks down -z (y up, OpenGL-like). Our camera (core/geometry/camera.h) looks down +z with y
// down, and its distortion acts on the same focal-normalised coordinates. With our
// cam_from_world (R_ours, t_ours) and D = diag(1, -1, -1):
//   R = D R_ours,   t = D t_ours           (flip the camera's y and z axes),
//   f, k1, k2 unchanged,
// so that P = (x_c, -y_c, -z_c) for our camera coordinates (x_c, y_c, z_c), p = (x_c/z_c,
// -y_c/z_c) and p' = (f x_d, -f y_d) for our distorted normalised point (x_d, y_d). The
// camera centre -Rᵀt is unchanged. The 2-D positions of the view lists are the keypoints
// (u, v) (our pixels, centre of the top-left pixel at (0, 0)) in Bundler's centred frame:
//   x = u - (width - 1) / 2,   y = (height - 1) / 2 - v,
// so the image's corner pixels' outer edges are at (±width/2, ±height/2) as Bundler states.
//
// Bundler has no principal point: it assumes the image centre. When a camera's principal point
// (cx, cy) is the centre ((width - 1) / 2, (height - 1) / 2) the Bundler camera reproduces our
// projection exactly; otherwise projecting with it is off by (cx - (width - 1) / 2,
// (height - 1) / 2 - cy) in Bundler's frame (the keys stay the measured positions). Numbers are
// written as the shortest decimal that reads back exactly.
#ifndef RECONDUIT_CORE_IO_BUNDLER_H_
#define RECONDUIT_CORE_IO_BUNDLER_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <filesystem>

namespace reconduit {

// Writes bundle.out and list.txt into `folder` (created if missing), each atomically.
// InvalidArgument when `rec` breaks the Reconstruction invariants or an image name is empty or
// holds a line break; Internal on I/O failure.
Status WriteBundler(const std::filesystem::path& folder, const Reconstruction& rec);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_BUNDLER_H_
