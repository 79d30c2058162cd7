#include "core/mvs/mvs_view.h"

#include "core/util/logging.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace reconduit {

Camera WorkingCamera(const Camera& camera, int max_side) {
  const int long_side = std::max(camera.width, camera.height);
  Camera working = camera;
  if (max_side > 0 && long_side > max_side) {
    const double scale = static_cast<double>(max_side) / long_side;
    working.width = std::max(1, static_cast<int>(std::lround(camera.width * scale)));
    working.height = std::max(1, static_cast<int>(std::lround(camera.height * scale)));
    // The x scale is exact; y's differs from it by at most half a pixel over the height, which
    // the resampling below absorbs (it maps through the true per-axis scales).
    const double s = static_cast<double>(working.width) / camera.width;
    working.focal = camera.focal * s;
    working.cx = (camera.cx + 0.5) * s - 0.5;
    working.cy = (camera.cy + 0.5) * s - 0.5;
  }
  working.k1 = 0.0;
  working.k2 = 0.0;
  return working;
}

PreparedView PrepareView(const cv::Mat& bgr,
                         const Camera& camera,
                         const Rigid3d& cam_from_world,
                         int max_side) {
  THROW_CHECK(bgr.type() == CV_8UC3) << "PrepareView needs an 8-bit BGR image";
  THROW_CHECK(bgr.cols == camera.width && bgr.rows == camera.height)
      << "image " << bgr.cols << "x" << bgr.rows << " does not match its camera " << camera.width
      << "x" << camera.height;
  const Camera working = WorkingCamera(camera, max_side);
  cv::Mat scaled = bgr;
  if (working.width != camera.width || working.height != camera.height) {
    cv::resize(bgr, scaled, cv::Size(working.width, working.height), 0, 0, cv::INTER_AREA);
  }
  // For every pixel of the working pinhole camera: its ray, distorted by the photo's lens, to
  // a pixel of the original photo, then to the scaled photo by the per-axis scales.
  const double sx = static_cast<double>(working.width) / camera.width;
  const double sy = static_cast<double>(working.height) / camera.height;
  cv::Mat map_x(working.height, working.width, CV_32FC1);
  cv::Mat map_y(working.height, working.width, CV_32FC1);
  for (int y = 0; y < working.height; ++y) {
    for (int x = 0; x < working.width; ++x) {
      const Eigen::Vector2d distorted = camera.Distort(working.NormalizedFromPixel({x, y}));
      const Eigen::Vector2d original = camera.PixelFromNormalized(distorted);
      map_x.at<float>(y, x) = static_cast<float>((original.x() + 0.5) * sx - 0.5);
      map_y.at<float>(y, x) = static_cast<float>((original.y() + 0.5) * sy - 0.5);
    }
  }
  PreparedView prepared;
  prepared.view.camera = working;
  prepared.view.cam_from_world = cam_from_world;
  cv::remap(scaled, prepared.color, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  const cv::Mat ones(scaled.size(), CV_8UC1, cv::Scalar(255));
  cv::remap(ones, prepared.valid, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  cv::Mat gray;
  cv::cvtColor(prepared.color, gray, cv::COLOR_BGR2GRAY);
  gray.convertTo(prepared.view.gray, CV_32FC1);
  return prepared;
}

}  // namespace reconduit
