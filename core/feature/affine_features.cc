#include "core/feature/affine_features.h"

#include "core/feature/sift.h"
#include "core/util/logging.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace reconduit {
namespace {

// Keypoints hashed by cells of `cell` pixels, to find the ones within a radius <= cell.
class KeypointGrid {
 public:
  explicit KeypointGrid(double cell) : cell_(std::max(cell, 1e-3)) {}

  void Add(const Keypoint& kp, int index) {
    cells_[Key(CellOf(kp.x), CellOf(kp.y))].push_back(index);
  }

  // The index of the nearest added keypoint within `radius` of `kp` (of `all`), or -1.
  int Nearest(const Keypoint& kp, const std::vector<Keypoint>& all, double radius) const {
    const long cx = CellOf(kp.x), cy = CellOf(kp.y);
    int best = -1;
    double best_d2 = radius * radius;
    for (long dy = -1; dy <= 1; ++dy) {
      for (long dx = -1; dx <= 1; ++dx) {
        const auto it = cells_.find(Key(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (int j : it->second) {
          const double ex = all[j].x - kp.x, ey = all[j].y - kp.y;
          const double d2 = ex * ex + ey * ey;
          if (d2 < best_d2 || (d2 == best_d2 && (best < 0 || j < best))) {
            best_d2 = d2;
            best = j;
          }
        }
      }
    }
    return best;
  }

 private:
  long CellOf(float v) const { return static_cast<long>(std::floor(v / cell_)); }
  static long long Key(long x, long y) {
    return (static_cast<long long>(x) << 32) ^ (y & 0xffffffffLL);
  }

  double cell_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

}  // namespace

bool AffineFeatureOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (max_image_side < 64 || max_image_side > 20000) {
    m << "max_image_side must be in [64, 20000], got " << max_image_side;
  } else if (max_tilt < 1 || max_tilt > 8) {
    m << "max_tilt must be in [1, 8], got " << max_tilt;
  } else if (!(contrast_threshold > 0.0 && contrast_threshold <= 1.0)) {
    m << "contrast_threshold must be in (0, 1], got " << contrast_threshold;
  } else if (!(duplicate_radius_px >= 0.0 && duplicate_radius_px <= 10.0)) {
    m << "duplicate_radius_px must be in [0, 10], got " << duplicate_radius_px;
  } else {
    return true;
  }
  if (error != nullptr) *error = m.str();
  return false;
}

std::vector<int> DropDuplicateKeypoints(const std::vector<Keypoint>& keypoints, double radius) {
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return keypoints[a].response > keypoints[b].response; });
  KeypointGrid grid(radius);
  std::vector<int> kept;
  for (int i : order) {
    if (radius > 0.0 && grid.Nearest(keypoints[i], keypoints, radius) >= 0) continue;
    grid.Add(keypoints[i], i);
    kept.push_back(i);
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

std::vector<int> MergeKeypoints(const std::vector<Keypoint>& base,
                                const std::vector<Keypoint>& extra,
                                double radius,
                                std::vector<Keypoint>* appended) {
  THROW_CHECK(appended != nullptr);
  KeypointGrid grid(radius);
  for (std::size_t i = 0; i < base.size(); ++i) grid.Add(base[i], static_cast<int>(i));
  std::vector<int> index(extra.size());
  for (std::size_t k = 0; k < extra.size(); ++k) {
    const int near = grid.Nearest(extra[k], base, radius);
    if (near >= 0) {
      index[k] = near;
    } else {
      index[k] = static_cast<int>(base.size() + appended->size());
      appended->push_back(extra[k]);
    }
  }
  return index;
}

FeatureSet ExtractAffineFeatures(const cv::Mat& image,
                                 const AffineFeatureOptions& options,
                                 cv::Size original_size) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  THROW_CHECK(!image.empty() && image.depth() == CV_8U) << "an 8-bit image is required";
  THROW_CHECK(original_size.width >= image.cols && original_size.height >= image.rows)
      << "the original must not be smaller than the image";
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  cv::Mat working = gray;
  const int long_side = std::max(gray.cols, gray.rows);
  if (long_side > options.max_image_side) {
    const double scale = static_cast<double>(options.max_image_side) / long_side;
    cv::resize(gray, working, cv::Size(), scale, scale, cv::INTER_AREA);
  }
  const double sx = static_cast<double>(working.cols) / original_size.width;
  const double sy = static_cast<double>(working.rows) / original_size.height;

  const cv::Ptr<cv::AffineFeature> asift = cv::AffineFeature::create(
      cv::SIFT::create(0, 3, options.contrast_threshold, 10.0, 1.6), options.max_tilt);
  std::vector<cv::KeyPoint> detected;
  cv::Mat sift_descriptors;
  asift->detectAndCompute(working, cv::noArray(), detected, sift_descriptors);

  std::vector<Keypoint> keypoints;
  keypoints.reserve(detected.size());
  for (const cv::KeyPoint& kp : detected) {
    Keypoint out;
    out.x = static_cast<float>((kp.pt.x + 0.5) / sx - 0.5);
    out.y = static_cast<float>((kp.pt.y + 0.5) / sy - 0.5);
    out.scale = static_cast<float>(kp.size / (0.5 * (sx + sy)));
    out.orientation = static_cast<float>(kp.angle * M_PI / 180.0);
    out.response = kp.response;
    keypoints.push_back(out);
  }
  std::vector<int> kept = DropDuplicateKeypoints(keypoints, options.duplicate_radius_px);
  // Strongest first, ties by position: the same order whatever order the tilts came back in.
  std::sort(kept.begin(), kept.end(), [&](int a, int b) {
    const Keypoint &p = keypoints[a], &q = keypoints[b];
    if (p.response != q.response) return p.response > q.response;
    if (p.y != q.y) return p.y < q.y;
    if (p.x != q.x) return p.x < q.x;
    return p.orientation < q.orientation;
  });
  const cv::Mat root = ToRootSiftBytes(sift_descriptors);
  FeatureSet features;
  features.image_width = original_size.width;
  features.image_height = original_size.height;
  features.descriptors.create(static_cast<int>(kept.size()), 128, CV_8U);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    features.keypoints.push_back(keypoints[kept[i]]);
    root.row(kept[i]).copyTo(features.descriptors.row(static_cast<int>(i)));
  }
  LOG_DEBUG << "affine features: " << detected.size() << " detected, " << kept.size()
            << " after dropping duplicates, in " << working.cols << "x" << working.rows;
  return features;
}

}  // namespace reconduit
