#include "core/mvs/image_noise.h"

#include "core/util/logging.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace reconduit {

double EstimateNoiseStddev(const cv::Mat& gray, const NoiseEstimateOptions& options) {
  THROW_CHECK(gray.type() == CV_32FC1 || gray.type() == CV_8UC1)
      << "noise estimate needs a single-channel image";
  THROW_CHECK(options.block_size >= 4) << "block_size must be >= 4, got " << options.block_size;
  THROW_CHECK(options.percentile >= 0.0 && options.percentile <= 1.0)
      << "percentile must be in [0, 1], got " << options.percentile;
  const int b = options.block_size;
  // The filter's valid part only: the image without its one-pixel border.
  const int blocks_x = (gray.cols - 2) / b, blocks_y = (gray.rows - 2) / b;
  if (blocks_x < 1 || blocks_y < 1) return 0.0;
  cv::Mat image;
  gray.convertTo(image, CV_32FC1);
  const cv::Mat kernel = (cv::Mat_<float>(3, 3) << 1, -2, 1, -2, 4, -2, 1, -2, 1);
  cv::Mat response;
  cv::filter2D(image, response, CV_32F, kernel);
  response = cv::abs(response(cv::Rect(1, 1, blocks_x * b, blocks_y * b)));
  // Responses that a clipped pixel (0 or 255) took part in.
  cv::Mat clipped = (image <= 0.0f) | (image >= 255.0f);
  cv::dilate(clipped, clipped, cv::Mat());
  cv::Mat clipped_share;
  clipped(cv::Rect(1, 1, blocks_x * b, blocks_y * b)).convertTo(clipped_share, CV_32F);
  cv::Mat block_means, block_clipped;
  const cv::Size blocks(blocks_x, blocks_y);
  cv::resize(response, block_means, blocks, 0.0, 0.0, cv::INTER_AREA);
  cv::resize(clipped_share, block_clipped, blocks, 0.0, 0.0, cv::INTER_AREA);
  std::vector<float> means;
  means.reserve(static_cast<std::size_t>(blocks_x) * blocks_y);
  for (int y = 0; y < block_means.rows; ++y) {
    const float* row = block_means.ptr<float>(y);
    const float* clipped_row = block_clipped.ptr<float>(y);
    for (int x = 0; x < block_means.cols; ++x) {
      if (row[x] > 0.0f && clipped_row[x] == 0.0f) means.push_back(row[x]);
    }
  }
  if (means.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(
      std::min<double>(means.size() - 1, std::floor(options.percentile * means.size())));
  std::nth_element(means.begin(), means.begin() + static_cast<std::ptrdiff_t>(k), means.end());
  return means[k] * std::sqrt(std::numbers::pi / 2.0) / 6.0;
}

}  // namespace reconduit
