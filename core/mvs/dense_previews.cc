#include "core/mvs/dense_previews.h"

#include "core/util/logging.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <vector>

namespace reconduit {
namespace {

// Nearest-neighbour downscale (an average would mix empty pixels into their neighbours).
cv::Mat Shrink(const cv::Mat& image, int max_side) {
  const int side = std::max(image.cols, image.rows);
  if (max_side <= 0 || side <= max_side) return image;
  const double scale = static_cast<double>(max_side) / side;
  cv::Mat small;
  cv::resize(image, small,
             cv::Size(std::max(1, static_cast<int>(image.cols * scale)),
                      std::max(1, static_cast<int>(image.rows * scale))),
             0, 0, cv::INTER_NEAREST);
  return small;
}

}  // namespace

cv::Mat RenderDepthPreview(const cv::Mat& depth, int max_side) {
  THROW_CHECK_EQ(depth.type(), CV_32FC1);
  const cv::Mat small = Shrink(depth, max_side);
  std::vector<float> values;
  for (int y = 0; y < small.rows; ++y)
    for (int x = 0; x < small.cols; ++x)
      if (small.at<float>(y, x) > 0) values.push_back(small.at<float>(y, x));
  cv::Mat out(small.size(), CV_8UC3, cv::Scalar::all(0));
  if (values.empty()) return out;
  auto percentile = [&](double p) {
    auto it = values.begin() + static_cast<std::ptrdiff_t>(p * (values.size() - 1));
    std::nth_element(values.begin(), it, values.end());
    return *it;
  };
  const float near = percentile(0.02), far = std::max(percentile(0.98), near * 1.0001f);
  cv::Mat level(small.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < small.rows; ++y) {
    for (int x = 0; x < small.cols; ++x) {
      const float d = small.at<float>(y, x);
      if (d <= 0) continue;
      // Turbo runs blue (0) to red (255): near is red.
      const float t = std::clamp((far - d) / (far - near), 0.0f, 1.0f);
      level.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(std::lround(t * 255));
    }
  }
  cv::Mat coloured;
  cv::applyColorMap(level, coloured, cv::COLORMAP_TURBO);
  coloured.copyTo(out, small > 0);
  return out;
}

cv::Mat RenderQualityPreview(const cv::Mat& quality, int max_views, int max_side) {
  THROW_CHECK_EQ(quality.type(), CV_8UC1);
  THROW_CHECK_GE(max_views, 2);
  const cv::Mat small = Shrink(quality, max_side);
  cv::Mat out(small.size(), CV_8UC3, cv::Scalar::all(0));
  for (int y = 0; y < small.rows; ++y) {
    for (int x = 0; x < small.cols; ++x) {
      const int q = small.at<std::uint8_t>(y, x);
      if (q == 0) continue;
      if (q == 1) {
        out.at<cv::Vec3b>(y, x) = {0, 0, 128};  // BGR dark red: nobody agrees.
        continue;
      }
      // Orange (2 views) to green (max_views and more), through yellow.
      const double t = std::min(1.0, (q - 2.0) / std::max(1, max_views - 2));
      const double red = t < 0.5 ? 255 : 255 * (1 - t) * 2;
      const double green = 140 + 115 * std::min(1.0, 2 * t);
      out.at<cv::Vec3b>(y, x) = {0, cv::saturate_cast<std::uint8_t>(green),
                                 cv::saturate_cast<std::uint8_t>(red)};
    }
  }
  return out;
}

}  // namespace reconduit
