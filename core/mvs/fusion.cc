#include "core/mvs/fusion.h"

#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace reconduit {
namespace {

// The relative depth error within which FusionResult::neighbor_agreement counts two maps as
// agreeing (issue 10's figure: "within 1 % relative depth"), whatever the fusion options.
constexpr float kAgreementDepthError = 0.01f;

// A view's pose and camera in float, with the back-projection precomputed.
struct ViewGeometry {
  Eigen::Matrix3f rotation;        // cam_from_world
  Eigen::Vector3f translation;     // cam_from_world
  Eigen::Matrix3f world_from_cam;  // rotation^T
  Eigen::Vector3f center;          // camera centre in the world
  Eigen::Matrix3f k;
  Eigen::Matrix3f k_inv;
  int width = 0, height = 0;
};

ViewGeometry MakeGeometry(const FusionView& view) {
  ViewGeometry g;
  g.rotation = view.cam_from_world.rotation.toRotationMatrix().cast<float>();
  g.translation = view.cam_from_world.translation.cast<float>();
  g.world_from_cam = g.rotation.transpose();
  g.center = view.cam_from_world.CenterInWorld().cast<float>();
  g.k = view.camera.K().cast<float>();
  g.k_inv = view.camera.K().inverse().cast<float>();
  g.width = view.camera.width;
  g.height = view.camera.height;
  return g;
}

// A depth-map pixel as a world point with a world normal.
struct Sample {
  Eigen::Vector3f point;
  Eigen::Vector3f normal;
};

class Fuser {
 public:
  Fuser(const std::vector<FusionView>& views, const FusionOptions& options)
      : views_(views), options_(options) {
    for (const FusionView& view : views) geometry_.push_back(MakeGeometry(view));
    cos_max_normal_angle_ =
        static_cast<float>(std::cos(options.max_normal_angle_deg * std::numbers::pi / 180.0));
    max_reprojection_sq_ =
        static_cast<float>(options.max_reprojection_error_px * options.max_reprojection_error_px);
    for (std::size_t v = 0; v < views.size(); ++v) {
      std::vector<int> neighbors = views[v].neighbors;
      if (neighbors.empty()) {
        for (std::size_t w = 0; w < views.size(); ++w)
          if (w != v) neighbors.push_back(static_cast<int>(w));
      }
      neighbors_.push_back(std::move(neighbors));
    }
  }

  Sample SampleAt(int view, int x, int y) const {
    const ViewGeometry& g = geometry_[view];
    const float depth = views_[view].map->depth.at<float>(y, x);
    const cv::Vec3f n = views_[view].map->normal.at<cv::Vec3f>(y, x);
    const Eigen::Vector3f in_cam =
        depth * (g.k_inv * Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), 1.0f));
    return {g.world_from_cam * (in_cam - g.translation),
            g.world_from_cam * Eigen::Vector3f(n[0], n[1], n[2])};
  }

  // Where `point` lands in `other`: the pixel, the point's depth there and the map's depth at
  // the pixel; false when it lands outside or on a pixel without depth.
  bool Lookup(
      const Eigen::Vector3f& point, int other, int* px, int* py, float* z, float* depth) const {
    const ViewGeometry& g = geometry_[other];
    const Eigen::Vector3f in_other = g.rotation * point + g.translation;
    if (in_other.z() <= 0.0f) return false;
    const Eigen::Vector3f h = g.k * in_other;
    *px = static_cast<int>(std::lround(h.x() / h.z()));
    *py = static_cast<int>(std::lround(h.y() / h.z()));
    if (*px < 0 || *py < 0 || *px >= g.width || *py >= g.height) return false;
    *depth = views_[other].map->depth.at<float>(*py, *px);
    *z = in_other.z();
    return *depth > 0.0f;
  }

  // The pixel of `other` confirming `sample` (seen at pixel (x, y) of `view`), if any.
  bool Confirms(int view, int x, int y, const Sample& sample, int other, int* ox, int* oy) const {
    int px = 0, py = 0;
    float z = 0.0f, depth = 0.0f;
    if (!Lookup(sample.point, other, &px, &py, &z, &depth)) return false;
    if (!ConfirmsAt(view, x, y, sample, other, px, py, z, depth)) return false;
    *ox = px;
    *oy = py;
    return true;
  }

  // Whether the depth `depth` of `other` at (px, py), where `sample` lands at depth z
  // (Lookup), confirms it: depth, normal and reprojection checks.
  bool ConfirmsAt(
      int view, int x, int y, const Sample& sample, int other, int px, int py, float z, float depth)
      const {
    if (std::abs(z - depth) > static_cast<float>(options_.max_relative_depth_error) * depth)
      return false;
    const Sample theirs = SampleAt(other, px, py);
    if (sample.normal.dot(theirs.normal) < cos_max_normal_angle_) return false;
    const ViewGeometry& mine = geometry_[view];
    const Eigen::Vector3f back = mine.k * (mine.rotation * theirs.point + mine.translation);
    if (back.z() <= 0.0f) return false;
    const float dx = back.x() / back.z() - static_cast<float>(x);
    const float dy = back.y() / back.z() - static_cast<float>(y);
    return dx * dx + dy * dy <= max_reprojection_sq_;
  }

  // The quality map of `view`, and its agreement with its neighbours' maps (FusionResult).
  cv::Mat Quality(int view, double* agreement) const {
    const cv::Mat& depth = views_[view].map->depth;
    cv::Mat quality(depth.size(), CV_8UC1, cv::Scalar(0));
    std::int64_t overlapping = 0, agreeing = 0;
    for (int y = 0; y < depth.rows; ++y) {
      for (int x = 0; x < depth.cols; ++x) {
        if (depth.at<float>(y, x) <= 0.0f) continue;
        const Sample sample = SampleAt(view, x, y);
        int agree = 1;
        for (int other : neighbors_[view]) {
          int px = 0, py = 0;
          float z = 0.0f, theirs = 0.0f;
          if (!Lookup(sample.point, other, &px, &py, &z, &theirs)) continue;
          ++overlapping;
          agreeing += std::abs(z - theirs) <= kAgreementDepthError * theirs;
          agree += ConfirmsAt(view, x, y, sample, other, px, py, z, theirs);
        }
        quality.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(std::min(agree, 255));
      }
    }
    *agreement = overlapping > 0 ? static_cast<double>(agreeing) / overlapping
                                 : std::numeric_limits<double>::quiet_NaN();
    return quality;
  }

  // Fuses the pixels of `view` that are not used yet, appending to `cloud`.
  void FuseView(int view, std::vector<cv::Mat>* used, DenseCloud* cloud) const {
    const cv::Mat& depth = views_[view].map->depth;
    std::vector<std::pair<int, cv::Point>> agreeing;
    for (int y = 0; y < depth.rows; ++y) {
      for (int x = 0; x < depth.cols; ++x) {
        if (depth.at<float>(y, x) <= 0.0f || (*used)[view].at<std::uint8_t>(y, x)) continue;
        const Sample sample = SampleAt(view, x, y);
        agreeing.assign(1, {view, cv::Point(x, y)});
        for (int other : neighbors_[view]) {
          int ox = 0, oy = 0;
          if (Confirms(view, x, y, sample, other, &ox, &oy) &&
              !(*used)[other].at<std::uint8_t>(oy, ox)) {
            agreeing.push_back({other, cv::Point(ox, oy)});
          }
        }
        if (static_cast<int>(agreeing.size()) < options_.min_views) continue;
        AddPoint(agreeing, used, cloud);
      }
    }
  }

 private:
  void AddPoint(const std::vector<std::pair<int, cv::Point>>& agreeing,
                std::vector<cv::Mat>* used,
                DenseCloud* cloud) const {
    Eigen::Vector3f position = Eigen::Vector3f::Zero(), normal = Eigen::Vector3f::Zero();
    Eigen::Vector3f color = Eigen::Vector3f::Zero();
    std::vector<int> seen_by;
    for (const auto& [v, p] : agreeing) {
      const Sample s = SampleAt(v, p.x, p.y);
      position += s.point;
      normal += s.normal;
      if (!views_[v].color.empty()) {
        const cv::Vec3b bgr = views_[v].color.at<cv::Vec3b>(p.y, p.x);
        color += Eigen::Vector3f(bgr[2], bgr[1], bgr[0]);
      } else {
        color += Eigen::Vector3f(128, 128, 128);
      }
      (*used)[v].at<std::uint8_t>(p.y, p.x) = 1;
      seen_by.push_back(views_[v].image_id);
    }
    const float n = static_cast<float>(agreeing.size());
    cloud->positions.push_back(position / n);
    cloud->normals.push_back(normal.normalized());
    const Eigen::Vector3f rgb = (color / n).array().round().min(255.0f).max(0.0f);
    cloud->colors.push_back(rgb.cast<std::uint8_t>());
    std::sort(seen_by.begin(), seen_by.end());
    seen_by.erase(std::unique(seen_by.begin(), seen_by.end()), seen_by.end());
    cloud->visibility.insert(cloud->visibility.end(), seen_by.begin(), seen_by.end());
    cloud->visibility_offsets.push_back(static_cast<std::uint32_t>(cloud->visibility.size()));
  }

  const std::vector<FusionView>& views_;
  const FusionOptions& options_;
  std::vector<ViewGeometry> geometry_;
  std::vector<std::vector<int>> neighbors_;
  float cos_max_normal_angle_ = 0.0f;
  float max_reprojection_sq_ = 0.0f;
};

void CheckViews(const std::vector<FusionView>& views) {
  for (std::size_t v = 0; v < views.size(); ++v) {
    const FusionView& view = views[v];
    THROW_CHECK(view.map != nullptr) << "view " << v << " has no depth map";
    THROW_CHECK(view.map->depth.type() == CV_32FC1 && view.map->normal.type() == CV_32FC3)
        << "view " << v << ": depth must be CV_32FC1 and normals CV_32FC3";
    THROW_CHECK(view.map->depth.cols == view.camera.width &&
                view.map->depth.rows == view.camera.height &&
                view.map->normal.size() == view.map->depth.size())
        << "view " << v << ": map size does not match the camera";
    THROW_CHECK(view.color.empty() ||
                (view.color.type() == CV_8UC3 && view.color.size() == view.map->depth.size()))
        << "view " << v << ": colour image must be CV_8UC3 of the map's size";
    for (int n : view.neighbors) {
      THROW_CHECK(n >= 0 && n < static_cast<int>(views.size()) && n != static_cast<int>(v))
          << "view " << v << ": bad neighbour index " << n;
    }
  }
}

}  // namespace

bool FusionOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (min_views < 2 || min_views > 32) {
    m << "min_views must be in [2, 32], got " << min_views;
  } else if (!(max_relative_depth_error > 0.0 && max_relative_depth_error < 1.0)) {
    m << "max_relative_depth_error must be in (0, 1), got " << max_relative_depth_error;
  } else if (!(max_reprojection_error_px > 0.0 && max_reprojection_error_px <= 100.0)) {
    m << "max_reprojection_error_px must be in (0, 100], got " << max_reprojection_error_px;
  } else if (!(max_normal_angle_deg > 0.0 && max_normal_angle_deg <= 180.0)) {
    m << "max_normal_angle_deg must be in (0, 180], got " << max_normal_angle_deg;
  }
  if (error) *error = m.str();
  return m.str().empty();
}

FusionResult FuseDepthMaps(const std::vector<FusionView>& views,
                           const FusionOptions& options,
                           const CancelToken& cancel) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  CheckViews(views);
  const Fuser fuser(views, options);
  FusionResult result;
  result.quality.resize(views.size());
  result.neighbor_agreement.resize(views.size());
  ParallelFor(
      0, views.size(),
      [&](std::size_t v) {
        cancel.ThrowIfCanceled();
        result.quality[v] = fuser.Quality(static_cast<int>(v), &result.neighbor_agreement[v]);
      },
      options.num_threads);
  std::vector<cv::Mat> used;
  for (const FusionView& view : views)
    used.emplace_back(view.map->depth.size(), CV_8UC1, cv::Scalar(0));
  for (std::size_t v = 0; v < views.size(); ++v) {
    cancel.ThrowIfCanceled();
    fuser.FuseView(static_cast<int>(v), &used, &result.cloud);
  }
  return result;
}

}  // namespace reconduit
