#include "core/mvs/patch_match.h"

#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace reconduit {
namespace {

constexpr float kEmptyCost = 2.0f;

// splitmix64: one well-mixed 64-bit value per (seed, pixel, iteration, draw).
std::uint64_t Mix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// A small generator of uniform floats in [0, 1) for one pixel's update.
class PixelRandom {
 public:
  PixelRandom(std::uint64_t seed, std::uint64_t pixel, std::uint64_t round)
      : state_(Mix(seed ^ Mix(pixel * 0x9e3779b97f4a7c15ULL + round))) {}
  float Uniform() {
    state_ = Mix(state_);
    return static_cast<float>(state_ >> 40) * (1.0f / 16777216.0f);
  }

 private:
  std::uint64_t state_;
};

// Homography pieces of one source: a pixel q of the reference maps, for the plane n.X = -delta
// (reference camera frame), to H q with H = A - b (K_ref^-T n / delta)^T.
struct SourceMapping {
  Eigen::Matrix3f A;  // K_src R K_ref^-1
  Eigen::Vector3f b;  // K_src t
  const cv::Mat* gray = nullptr;
};

// Mean and norm of the reference window (over the sampled pixels) at every pixel.
struct WindowStats {
  cv::Mat mean;      // CV_32FC1
  cv::Mat inv_norm;  // CV_32FC1: 1 / sqrt(sum (r - mean)^2); 0 for textureless windows.
};

class PatchMatcher {
 public:
  PatchMatcher(const PatchMatchInput& input, const PatchMatchOptions& options)
      : input_(input), options_(options) {
    const MvsView& ref = *input.reference;
    width_ = ref.camera.width;
    height_ = ref.camera.height;
    k_inv_ = ref.camera.K().inverse().cast<float>();
    for (const MvsView* src : input.sources) {
      const Rigid3d src_from_ref = src->cam_from_world * ref.cam_from_world.Inverse();
      const Eigen::Matrix3d k_src = src->camera.K();
      SourceMapping m;
      m.A = (k_src * src_from_ref.rotation.toRotationMatrix() * ref.camera.K().inverse())
                .cast<float>();
      m.b = (k_src * src_from_ref.translation).cast<float>();
      m.gray = &src->gray;
      sources_.push_back(m);
    }
    for (int dy = -options.window_radius; dy <= options.window_radius; dy += options.window_step)
      offsets_.push_back(dy);
    num_samples_ = static_cast<float>(offsets_.size() * offsets_.size());
    min_inv_depth_ = static_cast<float>(1.0 / input.max_depth);
    max_inv_depth_ = static_cast<float>(1.0 / input.min_depth);
    cos_max_normal_angle_ =
        static_cast<float>(std::cos(options.max_normal_angle_deg * std::numbers::pi / 180.0));
    top_k_ = std::min<int>(options.top_k, static_cast<int>(sources_.size()));
  }

  DepthMap Run(const CancelToken& cancel) {
    ComputeWindowStats();
    Initialize();
    for (int iteration = 0; iteration < options_.num_iterations; ++iteration) {
      for (int colour = 0; colour < 2; ++colour) {
        cancel.ThrowIfCanceled();
        ParallelFor(
            0, static_cast<std::size_t>(height_),
            [&](std::size_t row) { SweepRow(static_cast<int>(row), colour, iteration); },
            options_.num_threads);
      }
    }
    return Finish();
  }

 private:
  // The ray through pixel (x, y) at depth z = 1.
  Eigen::Vector3f Ray(float x, float y) const { return k_inv_ * Eigen::Vector3f(x, y, 1.0f); }

  bool Textured(int x, int y) const { return stats_.inv_norm.at<float>(y, x) > 0.0f; }

  void ComputeWindowStats() {
    const cv::Mat& gray = input_.reference->gray;
    stats_.mean = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(0));
    stats_.inv_norm = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(0));
    const float min_norm =
        static_cast<float>(options_.min_texture_stddev) * std::sqrt(num_samples_);
    const int r = options_.window_radius;
    ParallelFor(
        static_cast<std::size_t>(r), static_cast<std::size_t>(std::max(r, height_ - r)),
        [&](std::size_t row) {
          const int y = static_cast<int>(row);
          for (int x = r; x < width_ - r; ++x) {
            float sum = 0.0f, sum_sq = 0.0f;
            for (int dy : offsets_) {
              const float* line = gray.ptr<float>(y + dy);
              for (int dx : offsets_) {
                sum += line[x + dx];
                sum_sq += line[x + dx] * line[x + dx];
              }
            }
            const float mean = sum / num_samples_;
            const float norm = std::sqrt(std::max(0.0f, sum_sq - sum * mean));
            stats_.mean.at<float>(y, x) = mean;
            stats_.inv_norm.at<float>(y, x) = norm >= min_norm && norm > 0.0f ? 1.0f / norm : 0.0f;
          }
        },
        options_.num_threads);
  }

  // 1 - NCC of the reference window at (x, y) and its image in source `s` under homography H;
  // kEmptyCost when the window leaves the source image.
  //
  // Over a window of a few pixels the homography is affine to well under a hundredth of a
  // pixel, so the window is mapped by H's first-order expansion at its centre: no division per
  // sample, and the four corners bound every sample (an affine map keeps the window convex).
  // This and the single bounds test made the cost 1.3x faster than mapping each sample exactly
  // (perf, single thread, patch_match_test's fronto-parallel case: 2.55 s -> 1.99 s).
  float SourceCost(int x, int y, const Eigen::Matrix3f& H, const cv::Mat& src) const {
    const Eigen::Vector3f h =
        H * Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), 1.0f);
    if (h.z() <= 0.0f) return kEmptyCost;
    const float inv_z = 1.0f / h.z();
    const float uc = h.x() * inv_z, vc = h.y() * inv_z;
    // d(u, v) / d(x, y) at the centre.
    const float ux = (H(0, 0) - uc * H(2, 0)) * inv_z, uy = (H(0, 1) - uc * H(2, 1)) * inv_z;
    const float vx = (H(1, 0) - vc * H(2, 0)) * inv_z, vy = (H(1, 1) - vc * H(2, 1)) * inv_z;
    const float r = static_cast<float>(options_.window_radius);
    const float max_u = static_cast<float>(src.cols - 1), max_v = static_cast<float>(src.rows - 1);
    for (const float sx : {-r, r}) {
      for (const float sy : {-r, r}) {
        const float u = uc + ux * sx + uy * sy, v = vc + vx * sx + vy * sy;
        if (!(u >= 0.0f && v >= 0.0f && u < max_u && v < max_v)) return kEmptyCost;
      }
    }
    const cv::Mat& ref = input_.reference->gray;
    const float step = static_cast<float>(options_.window_step);
    const std::size_t stride = src.step1();
    const float* base = src.ptr<float>(0);
    float sum_rs = 0.0f, sum_s = 0.0f, sum_ss = 0.0f;
    for (int dy : offsets_) {
      const float* ref_line = ref.ptr<float>(y + dy) + x;
      const float fdy = static_cast<float>(dy);
      float u = uc - ux * r + uy * fdy, v = vc - vx * r + vy * fdy;
      for (int dx : offsets_) {
        const int iu = static_cast<int>(u), iv = static_cast<int>(v);
        const float fu = u - static_cast<float>(iu), fv = v - static_cast<float>(iv);
        const float* p = base + static_cast<std::size_t>(iv) * stride + iu;
        const float top = p[0] + fu * (p[1] - p[0]);
        const float bottom = p[stride] + fu * (p[stride + 1] - p[stride]);
        const float s = top + fv * (bottom - top);
        const float rv = ref_line[dx];
        sum_rs += rv * s;
        sum_s += s;
        sum_ss += s * s;
        u += ux * step;
        v += vx * step;
      }
    }
    const float var_s = sum_ss - sum_s * sum_s / num_samples_;
    if (var_s <= 1e-6f) return kEmptyCost;
    const float mean_r = stats_.mean.at<float>(y, x);
    const float ncc =
        (sum_rs - mean_r * sum_s) * stats_.inv_norm.at<float>(y, x) / std::sqrt(var_s);
    return std::clamp(1.0f - ncc, 0.0f, kEmptyCost);
  }

  // The multi-view cost of the plane (depth, normal) at pixel (x, y).
  float Cost(int x, int y, float depth, const Eigen::Vector3f& normal) const {
    const Eigen::Vector3f point = depth * Ray(static_cast<float>(x), static_cast<float>(y));
    const float delta = -normal.dot(point);
    if (delta <= 0.0f) return kEmptyCost;
    const Eigen::Vector3f m = k_inv_.transpose() * normal / delta;
    std::array<float, 16> costs;
    const int n = std::min<int>(static_cast<int>(sources_.size()), 16);
    for (int s = 0; s < n; ++s) {
      const Eigen::Matrix3f H = sources_[s].A - sources_[s].b * m.transpose();
      costs[s] = SourceCost(x, y, H, *sources_[s].gray);
    }
    std::partial_sort(costs.begin(), costs.begin() + top_k_, costs.begin() + n);
    float sum = 0.0f;
    for (int k = 0; k < top_k_; ++k) sum += costs[k];
    return sum / static_cast<float>(top_k_);
  }

  bool AcceptableNormal(const Eigen::Vector3f& normal, const Eigen::Vector3f& ray_unit) const {
    return -normal.dot(ray_unit) >= cos_max_normal_angle_;
  }

  // A random unit normal facing the camera within the allowed angle of the viewing ray.
  Eigen::Vector3f RandomNormal(PixelRandom& random, const Eigen::Vector3f& ray_unit) const {
    for (int attempt = 0; attempt < 8; ++attempt) {
      // Uniform on the sphere, then flipped towards the camera.
      const float z = 2.0f * random.Uniform() - 1.0f;
      const float phi = 2.0f * std::numbers::pi_v<float> * random.Uniform();
      const float rho = std::sqrt(std::max(0.0f, 1.0f - z * z));
      Eigen::Vector3f n(rho * std::cos(phi), rho * std::sin(phi), z);
      if (n.dot(ray_unit) > 0.0f) n = -n;
      if (AcceptableNormal(n, ray_unit)) return n;
    }
    return -ray_unit;
  }

  float RandomDepth(PixelRandom& random) const {
    return 1.0f / (min_inv_depth_ + random.Uniform() * (max_inv_depth_ - min_inv_depth_));
  }

  bool InDepthRange(float depth) const {
    const float inv = 1.0f / depth;
    return depth > 0.0f && inv >= min_inv_depth_ && inv <= max_inv_depth_;
  }

  std::size_t Index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + x;
  }

  void Initialize() {
    const std::size_t n = static_cast<std::size_t>(width_) * height_;
    depth_.assign(n, 0.0f);
    normal_.assign(n, Eigen::Vector3f(0, 0, -1));
    cost_.assign(n, kEmptyCost);
    std::vector<char> seeded(n, 0);
    for (const DepthSeed& seed : input_.seeds) {
      const int x = static_cast<int>(std::lround(seed.pixel.x()));
      const int y = static_cast<int>(std::lround(seed.pixel.y()));
      if (x < 0 || y < 0 || x >= width_ || y >= height_) continue;
      if (!InDepthRange(static_cast<float>(seed.depth))) continue;
      depth_[Index(x, y)] = static_cast<float>(seed.depth);
      // Fronto-parallel: the sparse point says where the surface is, not how it is tilted.
      normal_[Index(x, y)] = Eigen::Vector3f(0.0f, 0.0f, -1.0f);
      seeded[Index(x, y)] = 1;
    }
    ParallelFor(
        0, static_cast<std::size_t>(height_),
        [&](std::size_t row) {
          const int y = static_cast<int>(row);
          for (int x = 0; x < width_; ++x) {
            if (!Inside(x, y) || !Textured(x, y)) continue;
            const std::size_t i = Index(x, y);
            if (!seeded[i]) {
              PixelRandom random(options_.seed, i, 0);
              const Eigen::Vector3f ray =
                  Ray(static_cast<float>(x), static_cast<float>(y)).normalized();
              depth_[i] = RandomDepth(random);
              normal_[i] = RandomNormal(random, ray);
            }
            cost_[i] = Cost(x, y, depth_[i], normal_[i]);
          }
        },
        options_.num_threads);
  }

  bool Inside(int x, int y) const {
    const int r = options_.window_radius;
    return x >= r && y >= r && x < width_ - r && y < height_ - r;
  }

  // Keeps (depth, normal) at pixel i if it costs less than what is there.
  void TryPlane(
      int x, int y, float depth, const Eigen::Vector3f& normal, const Eigen::Vector3f& ray_unit) {
    if (!InDepthRange(depth) || !AcceptableNormal(normal, ray_unit)) return;
    const std::size_t i = Index(x, y);
    const float cost = Cost(x, y, depth, normal);
    if (cost < cost_[i]) {
      cost_[i] = cost;
      depth_[i] = depth;
      normal_[i] = normal;
    }
  }

  void SweepRow(int y, int colour, int iteration) {
    // Neighbours of the other colour: 1 and 3 pixels away along the axes.
    static constexpr std::array<std::array<int, 2>, 8> kNeighbors = {
        {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {-3, 0}, {3, 0}, {0, -3}, {0, 3}}};
    for (int x = (y + colour) % 2; x < width_; x += 2) {
      if (!Inside(x, y) || !Textured(x, y)) continue;
      const Eigen::Vector3f ray = Ray(static_cast<float>(x), static_cast<float>(y));
      const Eigen::Vector3f ray_unit = ray.normalized();
      // Propagation: the neighbour's plane, intersected with this pixel's ray.
      for (const auto& [dx, dy] : kNeighbors) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
        const std::size_t j = Index(nx, ny);
        if (cost_[j] >= kEmptyCost) continue;
        const Eigen::Vector3f& n = normal_[j];
        const Eigen::Vector3f point =
            depth_[j] * Ray(static_cast<float>(nx), static_cast<float>(ny));
        const float denom = n.dot(ray);
        if (std::abs(denom) < 1e-6f) continue;
        const float depth = n.dot(point) / denom;
        const std::size_t i = Index(x, y);
        if (depth == depth_[i] && n == normal_[i]) continue;
        TryPlane(x, y, depth, n, ray_unit);
      }
      Refine(x, y, iteration, ray_unit);
    }
  }

  // Random changes of the pixel's plane: a new depth, a new normal, and perturbations of both
  // whose size halves with each iteration (from +-4 % of the depth and about +-15 degrees),
  // plus a ten times finer depth step, so that the last iterations polish to well under a
  // thousandth of the depth.
  void Refine(int x, int y, int iteration, const Eigen::Vector3f& ray_unit) {
    const std::size_t i = Index(x, y);
    PixelRandom random(options_.seed, i, static_cast<std::uint64_t>(iteration) + 1);
    const float scale = std::pow(0.5f, static_cast<float>(iteration));
    TryPlane(x, y, RandomDepth(random), normal_[i], ray_unit);
    TryPlane(x, y, depth_[i], RandomNormal(random, ray_unit), ray_unit);
    auto centred = [&random] { return 2.0f * random.Uniform() - 1.0f; };
    Eigen::Vector3f perturbed =
        normal_[i] + 0.25f * scale * Eigen::Vector3f(centred(), centred(), centred());
    perturbed.normalize();
    TryPlane(x, y, depth_[i] * (1.0f + 0.04f * scale * centred()), perturbed, ray_unit);
    TryPlane(x, y, depth_[i] * (1.0f + 0.004f * scale * centred()), normal_[i], ray_unit);
  }

  DepthMap Finish() const {
    DepthMap map;
    map.depth = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(0));
    map.normal = cv::Mat(height_, width_, CV_32FC3, cv::Scalar(0, 0, 0));
    map.cost = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(kEmptyCost));
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const std::size_t i = Index(x, y);
        if (cost_[i] > options_.max_cost) continue;
        map.depth.at<float>(y, x) = depth_[i];
        map.normal.at<cv::Vec3f>(y, x) = {normal_[i].x(), normal_[i].y(), normal_[i].z()};
        map.cost.at<float>(y, x) = cost_[i];
      }
    }
    return map;
  }

  const PatchMatchInput& input_;
  const PatchMatchOptions& options_;
  int width_ = 0, height_ = 0;
  Eigen::Matrix3f k_inv_;
  std::vector<SourceMapping> sources_;
  std::vector<int> offsets_;
  float num_samples_ = 0.0f;
  float min_inv_depth_ = 0.0f, max_inv_depth_ = 0.0f;
  float cos_max_normal_angle_ = 0.0f;
  int top_k_ = 1;
  WindowStats stats_;
  std::vector<float> depth_;
  std::vector<Eigen::Vector3f> normal_;
  std::vector<float> cost_;
};

void CheckInput(const PatchMatchInput& input) {
  THROW_CHECK(input.reference != nullptr) << "no reference view";
  THROW_CHECK(!input.sources.empty()) << "dense matching needs at least one source view";
  THROW_CHECK(input.sources.size() <= 16)
      << "at most 16 source views, got " << input.sources.size();
  THROW_CHECK(input.min_depth > 0.0 && input.min_depth < input.max_depth &&
              std::isfinite(input.max_depth))
      << "bad depth range [" << input.min_depth << ", " << input.max_depth << "]";
  std::vector<const MvsView*> views = input.sources;
  views.push_back(input.reference);
  for (const MvsView* view : views) {
    THROW_CHECK(view != nullptr);
    THROW_CHECK(view->gray.type() == CV_32FC1) << "grey images must be CV_32FC1";
    THROW_CHECK(view->gray.cols == view->camera.width && view->gray.rows == view->camera.height)
        << "image " << view->gray.cols << "x" << view->gray.rows << " does not match its camera "
        << view->camera.width << "x" << view->camera.height;
    THROW_CHECK(view->camera.k1 == 0.0 && view->camera.k2 == 0.0)
        << "dense matching needs undistorted images";
  }
}

}  // namespace

bool PatchMatchOptions::Check(std::string* error) const {
  std::ostringstream m;
  if (window_radius < 1 || window_radius > 15) {
    m << "window_radius must be in [1, 15], got " << window_radius;
  } else if (window_step < 1 || window_step > window_radius) {
    m << "window_step must be in [1, window_radius], got " << window_step;
  } else if (num_iterations < 1 || num_iterations > 50) {
    m << "num_iterations must be in [1, 50], got " << num_iterations;
  } else if (top_k < 1 || top_k > 16) {
    m << "top_k must be in [1, 16], got " << top_k;
  } else if (!(min_texture_stddev >= 0.0)) {
    m << "min_texture_stddev must be >= 0, got " << min_texture_stddev;
  } else if (!(max_cost > 0.0 && max_cost <= 2.0)) {
    m << "max_cost must be in (0, 2], got " << max_cost;
  } else if (!(max_normal_angle_deg > 0.0 && max_normal_angle_deg < 90.0)) {
    m << "max_normal_angle_deg must be in (0, 90), got " << max_normal_angle_deg;
  }
  if (error) *error = m.str();
  return m.str().empty();
}

DepthMap ComputeDepthMap(const PatchMatchInput& input,
                         const PatchMatchOptions& options,
                         const CancelToken& cancel) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;
  CheckInput(input);
  PatchMatcher matcher(input, options);
  return matcher.Run(cancel);
}

}  // namespace reconduit
