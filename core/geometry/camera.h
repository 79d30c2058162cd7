// The camera model: pinhole with one focal length (square pixels), a principal point and
// two-parameter radial distortion.
//
// Conventions (used everywhere in core/):
// - The camera looks down +z; x points right and y down in the image.
// - Pixel coordinates put the CENTRE of the top-left pixel at (0, 0), as OpenCV does, so the
//   image centre is ((width - 1) / 2, (height - 1) / 2). Writers of formats that put pixel
//   centres at 0.5 (COLMAP text models) add 0.5 on export.
// - Distortion acts on normalised coordinates (x, y) = (X/Z, Y/Z):
//     r² = x² + y²,  (x_d, y_d) = (x, y) · (1 + k1 r² + k2 r⁴),
//     pixel = (f x_d + cx, f y_d + cy).
//   This is COLMAP's RADIAL model and the first two terms of OpenCV's and Bundler's.
// - Focal length and principal point are in pixels of the image the camera describes
//   (for exports: the original upload, not a working resolution).
#ifndef RECONDUIT_CORE_GEOMETRY_CAMERA_H_
#define RECONDUIT_CORE_GEOMETRY_CAMERA_H_

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <ostream>
#include <string>

namespace reconduit {

struct Camera {
  int width = 0;       // Image width in pixels, > 0.
  int height = 0;      // Image height in pixels, > 0.
  double focal = 0.0;  // Focal length in pixels, > 0.
  double cx = 0.0;     // Principal point x in pixels.
  double cy = 0.0;     // Principal point y in pixels.
  double k1 = 0.0;     // Radial distortion, r² coefficient.
  double k2 = 0.0;     // Radial distortion, r⁴ coefficient.

  // A distortion-free camera with the principal point at the image centre.
  static Camera FromFocal(int width, int height, double focal);

  // Intrinsic matrix K = [f 0 cx; 0 f cy; 0 0 1] (distortion not included).
  Eigen::Matrix3d K() const;

  // Normalised image coordinates -> distorted normalised coordinates.
  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;
  // Inverse of Distort, by Newton's method on the radius (radial distortion keeps the
  // direction, so the 2-D problem is 1-D). Valid where r_d(r) is increasing; returns nullopt
  // for points beyond the radius where a strongly negative distortion folds back.
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& distorted) const;

  // Projects a point in camera coordinates to pixels. nullopt when the point is not in
  // front of the camera (z <= 0). The pixel may fall outside the image.
  std::optional<Eigen::Vector2d> ImgFromCam(const Eigen::Vector3d& point_in_cam) const;
  // Back-projects a pixel to the point on its viewing ray at depth z = 1 (undistorted).
  // nullopt where Undistort fails.
  std::optional<Eigen::Vector3d> CamFromImg(const Eigen::Vector2d& pixel) const;

  // Pixel <-> normalised coordinates, ignoring distortion.
  Eigen::Vector2d NormalizedFromPixel(const Eigen::Vector2d& pixel) const {
    return {(pixel.x() - cx) / focal, (pixel.y() - cy) / focal};
  }
  Eigen::Vector2d PixelFromNormalized(const Eigen::Vector2d& normalized) const {
    return {focal * normalized.x() + cx, focal * normalized.y() + cy};
  }

  bool InImage(const Eigen::Vector2d& pixel) const {
    return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() < width - 0.5 &&
           pixel.y() < height - 0.5;
  }

  // Horizontal field of view in degrees (ignoring distortion).
  double FieldOfViewXDeg() const;

  // The same camera for an image scaled by `scale` (e.g. 0.5 for half resolution): focal and
  // principal point follow the pixel-centre convention above; distortion is unchanged.
  Camera Scaled(double scale) const;

  // False, with a message, for non-positive size or focal, or non-finite values.
  bool Check(std::string* error) const;
};

std::ostream& operator<<(std::ostream& os, const Camera& camera);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_GEOMETRY_CAMERA_H_
