#include "core/feature/sift.h"

#include "core/util/logging.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <climits>
#include <cmath>
#include <numeric>
#include <sstream>

namespace reconduit {
namespace {

// The position bias of OpenCV's SIFT with its doubled first octave, in the pixels of the
// image it is given.
constexpr double kOpenCvSiftOffset = 0.25;

// OpenCV's octave of a keypoint: -1 for the doubled first octave (KeyPoint::octave packs the
// octave in its low byte, the layer above it).
int OpenCvOctave(const cv::KeyPoint& keypoint) {
  const int octave = keypoint.octave & 255;
  return octave < 128 ? octave : (-128 | octave);
}

// SIFT candidates in working pixels, bias-free: pixel centres at integers.
struct Candidates {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  // RootSIFT bytes (ToRootSiftBytes), a row per keypoint: a quarter of
                        // OpenCV's floats, for the hundreds of thousands of a large photo.
};

// One region of one image to run SIFT on, and which of its keypoints to keep.
struct Piece {
  cv::Rect region;      // In the pixels of the image.
  cv::Rect keep;        // Keypoints whose position falls here are kept (image pixels).
  int max_octave;       // Keypoints of coarser octaves are left to a coarser image.
  double to_working_x;  // Working pixels per image pixel.
  double to_working_y;
};

void DetectPiece(const cv::Mat& image, const Piece& piece, cv::SIFT& sift, Candidates* out) {
  // A tile is copied, so that the pixels around it do not take part (as at the image's
  // border); the whole image is used as it is.
  const bool whole = piece.region == cv::Rect(0, 0, image.cols, image.rows);
  const cv::Mat region = whole ? image : image(piece.region).clone();
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  // One pass: detect() followed by compute() would build the Gaussian pyramid twice, which
  // costs more than describing the candidates that the selection then drops.
  sift.detectAndCompute(region, cv::noArray(), keypoints, descriptors);
  descriptors = ToRootSiftBytes(descriptors);
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    cv::KeyPoint kp = keypoints[i];
    if (OpenCvOctave(kp) > piece.max_octave) continue;
    // OpenCV 4.6 doubles the image with INTER_LINEAR (sample k of the doubled image lies at
    // k/2 - 1/4 in the input) and then halves positions, so every keypoint is reported 1/4
    // pixel right of and below where it is (sift_test pins this with blobs at known sub-pixel
    // centres).
    const double x = kp.pt.x - kOpenCvSiftOffset + piece.region.x;
    const double y = kp.pt.y - kOpenCvSiftOffset + piece.region.y;
    // Pixel p of a piece's own cut decides; a keypoint at the very edge belongs to one piece.
    const int px = static_cast<int>(std::floor(x + 0.5));
    const int py = static_cast<int>(std::floor(y + 0.5));
    if (!piece.keep.contains(cv::Point(px, py))) continue;
    // Pixel centres at integers in both images: x_working + 0.5 = (x + 0.5) * to_working.
    kp.pt.x = static_cast<float>((x + 0.5) * piece.to_working_x - 0.5);
    kp.pt.y = static_cast<float>((y + 0.5) * piece.to_working_y - 0.5);
    kp.size = static_cast<float>(kp.size * 0.5 * (piece.to_working_x + piece.to_working_y));
    out->keypoints.push_back(kp);
    out->descriptors.push_back(descriptors.row(static_cast<int>(i)));
  }
}

// The cuts of `length` pixels into pieces of at most `max_part` pixels, as even as possible.
std::vector<std::pair<int, int>> Cuts(int length, int max_part) {
  const int parts = (length + max_part - 1) / max_part;
  std::vector<std::pair<int, int>> cuts;
  for (int k = 0; k < parts; ++k) {
    cuts.emplace_back(static_cast<int>(static_cast<long>(length) * k / parts),
                      static_cast<int>(static_cast<long>(length) * (k + 1) / parts));
  }
  return cuts;
}

// Appends the candidates of `image` (whose pixels are `to_working_*` working pixels), whole
// when it is small enough, else in tiles and a 4x smaller copy (see sift.h).
void DetectLevel(const cv::Mat& image,
                 double to_working_x,
                 double to_working_y,
                 const SiftOptions& options,
                 cv::SIFT& sift,
                 Candidates* out) {
  const cv::Rect all(0, 0, image.cols, image.rows);
  if (image.total() <= static_cast<std::size_t>(options.max_tile_pixels)) {
    DetectPiece(image, {all, all, INT_MAX, to_working_x, to_working_y}, sift, out);
    return;
  }
  const int max_core = static_cast<int>(std::sqrt(static_cast<double>(options.max_tile_pixels))) -
                       2 * kSiftTileMargin;
  for (const auto& [y0, y1] : Cuts(image.rows, max_core)) {
    for (const auto& [x0, x1] : Cuts(image.cols, max_core)) {
      const cv::Rect keep(x0, y0, x1 - x0, y1 - y0);
      const cv::Rect region =
          cv::Rect(x0 - kSiftTileMargin, y0 - kSiftTileMargin, keep.width + 2 * kSiftTileMargin,
                   keep.height + 2 * kSiftTileMargin) &
          all;
      DetectPiece(image, {region, keep, 0, to_working_x, to_working_y}, sift, out);
    }
  }
  cv::Mat quarter;
  cv::resize(image, quarter,
             cv::Size(std::max(1, (image.cols + 2) / 4), std::max(1, (image.rows + 2) / 4)), 0, 0,
             cv::INTER_AREA);
  DetectLevel(quarter, to_working_x * image.cols / quarter.cols,
              to_working_y * image.rows / quarter.rows, options, sift, out);
}

}  // namespace

bool SiftOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (max_image_side < 64 || max_image_side > 20000) {
    m << "max_image_side must be in [64, 20000], got " << max_image_side;
  } else if (max_features < kMinMaxFeatures || max_features > kMaxMaxFeatures) {
    m << "max_features must be in [" << kMinMaxFeatures << ", " << kMaxMaxFeatures << "], got "
      << max_features;
  } else if (!(spread_fraction >= 0.0 && spread_fraction <= 1.0)) {
    m << "spread_fraction must be in [0, 1], got " << spread_fraction;
  } else if (grid_cells < 1 || grid_cells > 64) {
    m << "grid_cells must be in [1, 64], got " << grid_cells;
  } else if (!(contrast_threshold > 0.0 && contrast_threshold <= 1.0)) {
    m << "contrast_threshold must be in (0, 1], got " << contrast_threshold;
  } else if (min_features < 0 || min_features > kMaxMaxFeatures) {
    m << "min_features must be in [0, " << kMaxMaxFeatures << "], got " << min_features;
  } else if (!(min_contrast_threshold > 0.0 && min_contrast_threshold <= contrast_threshold)) {
    m << "min_contrast_threshold must be in (0, contrast_threshold], got "
      << min_contrast_threshold;
  } else if (upsample_below_side < 0 || upsample_below_side > 20000) {
    m << "upsample_below_side must be in [0, 20000], got " << upsample_below_side;
  } else if (!(edge_threshold >= 1.0 && edge_threshold <= 100.0)) {
    m << "edge_threshold must be in [1, 100], got " << edge_threshold;
  } else if (octave_layers < 1 || octave_layers > 8) {
    m << "octave_layers must be in [1, 8], got " << octave_layers;
  } else if (max_tile_pixels < kMinSiftTilePixels || max_tile_pixels > (1 << 30)) {
    m << "max_tile_pixels must be in [" << kMinSiftTilePixels << ", " << (1 << 30) << "], got "
      << max_tile_pixels;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::vector<int> SelectSpreadKeypoints(const std::vector<cv::KeyPoint>& candidates,
                                       int image_width,
                                       int image_height,
                                       int max_features,
                                       double spread_fraction,
                                       int grid_cells) {
  std::vector<int> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  // Stable on ties (index order) so that results are deterministic.
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return candidates[a].response > candidates[b].response; });
  if (static_cast<int>(order.size()) <= max_features) return order;

  const int num_strong = static_cast<int>(std::lround((1.0 - spread_fraction) * max_features));
  std::vector<int> selected(order.begin(), order.begin() + num_strong);

  // Square cells, `grid_cells` along the longer side.
  const double cell = static_cast<double>(std::max(image_width, image_height)) / grid_cells;
  const int cols = std::max(1, static_cast<int>(std::ceil(image_width / cell)));
  const int rows = std::max(1, static_cast<int>(std::ceil(image_height / cell)));
  std::vector<std::vector<int>> buckets(static_cast<std::size_t>(cols) * rows);
  for (std::size_t i = num_strong; i < order.size(); ++i) {
    const cv::KeyPoint& kp = candidates[order[i]];
    const int cx = std::clamp(static_cast<int>(kp.pt.x / cell), 0, cols - 1);
    const int cy = std::clamp(static_cast<int>(kp.pt.y / cell), 0, rows - 1);
    buckets[static_cast<std::size_t>(cy) * cols + cx].push_back(order[i]);  // Strongest first.
  }
  std::vector<std::size_t> next(buckets.size(), 0);
  bool any = true;
  while (static_cast<int>(selected.size()) < max_features && any) {
    any = false;
    for (std::size_t b = 0; b < buckets.size() && static_cast<int>(selected.size()) < max_features;
         ++b) {
      if (next[b] < buckets[b].size()) {
        selected.push_back(buckets[b][next[b]++]);
        any = true;
      }
    }
  }
  return selected;
}

cv::Mat ToRootSiftBytes(const cv::Mat& sift_descriptors) {
  THROW_CHECK(sift_descriptors.empty() ||
              (sift_descriptors.cols == 128 && sift_descriptors.type() == CV_32F));
  cv::Mat bytes(sift_descriptors.rows, 128, CV_8U);
  for (int r = 0; r < sift_descriptors.rows; ++r) {
    const float* in = sift_descriptors.ptr<float>(r);
    std::uint8_t* out = bytes.ptr<std::uint8_t>(r);
    double l1 = 0.0;
    for (int c = 0; c < 128; ++c) l1 += std::abs(in[c]);
    const double inv = l1 > 0.0 ? 1.0 / l1 : 0.0;
    for (int c = 0; c < 128; ++c) {
      const double v = std::sqrt(std::abs(in[c]) * inv);
      out[c] = static_cast<std::uint8_t>(std::lround(std::min(255.0, 512.0 * v)));
    }
  }
  return bytes;
}

FeatureSet ExtractSiftFeatures(const cv::Mat& image, const SiftOptions& options) {
  return ExtractSiftFeatures(image, options, image.size());
}

namespace {

// The candidates of `working`, with the passes of SiftOptions::min_features: the contrast
// threshold halves while a pass finds fewer than min_features, then a small working copy is
// detected at twice its size at the lowest threshold. Keeps the pass with the most.
Candidates DetectAdaptively(const cv::Mat& working,
                            const SiftOptions& options,
                            SiftDetection* detection) {
  const auto detect = [&](const cv::Mat& image, double to_working, double contrast) {
    cv::Ptr<cv::SIFT> sift =
        cv::SIFT::create(0, options.octave_layers, contrast, options.edge_threshold, 1.6);
    Candidates found;
    DetectLevel(image, to_working, to_working, options, *sift, &found);
    ++detection->passes;
    return found;
  };
  double contrast = options.contrast_threshold;
  Candidates best = detect(working, 1.0, contrast);
  detection->contrast_threshold = contrast;
  const int wanted = std::min(options.min_features, options.max_features);
  const auto enough = [&] { return static_cast<int>(best.keypoints.size()) >= wanted; };
  while (!enough() && contrast > options.min_contrast_threshold) {
    contrast = std::max(options.min_contrast_threshold, 0.5 * contrast);
    Candidates more = detect(working, 1.0, contrast);
    if (more.keypoints.size() > best.keypoints.size()) {
      best = std::move(more);
      detection->contrast_threshold = contrast;
    }
  }
  if (!enough() && std::max(working.cols, working.rows) < options.upsample_below_side) {
    // Pixel centres at integers in both copies (INTER_LINEAR maps them so): to_working 0.5.
    cv::Mat doubled;
    cv::resize(working, doubled, cv::Size(2 * working.cols, 2 * working.rows), 0, 0,
               cv::INTER_LINEAR);
    Candidates more = detect(doubled, 0.5, contrast);
    if (more.keypoints.size() > best.keypoints.size()) {
      best = std::move(more);
      detection->contrast_threshold = contrast;
      detection->upsampled = true;
    }
  }
  detection->candidates = static_cast<int>(best.keypoints.size());
  return best;
}

}  // namespace

FeatureSet ExtractSiftFeatures(const cv::Mat& image,
                               const SiftOptions& options,
                               cv::Size original_size,
                               SiftDetection* detection) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK(!image.empty() && image.depth() == CV_8U) << "an 8-bit image is required";
  THROW_CHECK(original_size.width >= image.cols && original_size.height >= image.rows)
      << "the original must not be smaller than the image";

  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  const int long_side = std::max(gray.cols, gray.rows);
  cv::Mat working = gray;
  if (long_side > options.max_image_side) {
    const double scale = static_cast<double>(options.max_image_side) / long_side;
    cv::resize(gray, working, cv::Size(), scale, scale, cv::INTER_AREA);
  }
  // The working size is rounded to whole pixels: use the actual per-axis factors.
  const double sx = static_cast<double>(working.cols) / original_size.width;
  const double sy = static_cast<double>(working.rows) / original_size.height;

  SiftDetection local_detection;
  if (detection == nullptr) detection = &local_detection;
  *detection = SiftDetection();
  Candidates candidates = DetectAdaptively(working, options, detection);
  LOG_DEBUG << "sift: " << candidates.keypoints.size() << " candidates in " << working.cols << "x"
            << working.rows << " (contrast " << detection->contrast_threshold
            << (detection->upsampled ? ", upsampled" : "") << ")";
  const std::vector<int> chosen =
      SelectSpreadKeypoints(candidates.keypoints, working.cols, working.rows, options.max_features,
                            options.spread_fraction, options.grid_cells);
  std::vector<cv::KeyPoint> keypoints;
  keypoints.reserve(chosen.size());
  cv::Mat descriptors(static_cast<int>(chosen.size()), 128, CV_8U);
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    keypoints.push_back(candidates.keypoints[chosen[i]]);
    candidates.descriptors.row(chosen[i]).copyTo(descriptors.row(static_cast<int>(i)));
  }

  FeatureSet features;
  features.image_width = original_size.width;
  features.image_height = original_size.height;
  features.keypoints.reserve(keypoints.size());
  for (const cv::KeyPoint& kp : keypoints) {
    Keypoint out;
    // Pixel centres at integers in both images: x_orig + 0.5 = (x_work + 0.5) / s.
    out.x = static_cast<float>((kp.pt.x + 0.5) / sx - 0.5);
    out.y = static_cast<float>((kp.pt.y + 0.5) / sy - 0.5);
    out.scale = static_cast<float>(kp.size / (0.5 * (sx + sy)));
    out.orientation = static_cast<float>(kp.angle * M_PI / 180.0);
    out.response = kp.response;
    features.keypoints.push_back(out);
  }
  features.descriptors = descriptors;
  return features;
}

}  // namespace reconduit
