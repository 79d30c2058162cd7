#include "core/mvs/patch_match.h"

#include "core/mvs/image_noise.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <Eigen/Dense>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace reconduit {
namespace {

constexpr float kEmptyCost = 2.0f;
// Added to the multi-view cost for each of the top_k sources that cannot see the window (see
// PatchMatcher::Cost): with the default max_cost 0.6 and top_k 2, a pixel one source sees needs
// an NCC above 0.5 with it instead of 0.4 on average over two.
constexpr float kMissingSourcePenalty = 0.2f;

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

// The matching window's samples, flattened: sample k sits at (dx[k], dy[k]) from the window's
// centre. The arrays are padded to a multiple of 8 with centre samples of weight 0, so that the
// AVX2 kernel reads whole vectors (summing the 25th of the default 25 samples separately, with
// scalar code, was 1.5x slower than the padded 32: benchmark at 768 x 512, 1 thread).
struct WindowLayout {
  std::vector<float> dx, dy, weight;
  int count = 0;   // Real samples.
  int padded = 0;  // count rounded up to a multiple of 8.
};

// The affine map of a window into a source (the homography's first-order expansion at the
// window's centre): sample (dx, dy) lands at (uc + ux dx + uy dy, vc + vx dx + vy dy).
struct AffineWindow {
  float uc, vc, ux, uy, vx, vy;
};

// Sums over the window of r s, s and s^2, where r are the reference samples (`ref`, padded
// with zeros) and s the source's bilinear samples at the mapped positions (all inside).
struct SampleSums {
  float rs = 0.0f, s = 0.0f, ss = 0.0f;
};

SampleSums SumSamplesScalar(const float* base,
                            std::size_t stride,
                            const AffineWindow& w,
                            const WindowLayout& layout,
                            const float* ref) {
  SampleSums sums;
  for (int k = 0; k < layout.count; ++k) {
    const float u = w.uc + w.ux * layout.dx[k] + w.uy * layout.dy[k];
    const float v = w.vc + w.vx * layout.dx[k] + w.vy * layout.dy[k];
    const int iu = static_cast<int>(u), iv = static_cast<int>(v);
    const float fu = u - static_cast<float>(iu), fv = v - static_cast<float>(iv);
    const float* p = base + static_cast<std::size_t>(iv) * stride + iu;
    const float top = p[0] + fu * (p[1] - p[0]);
    const float bottom = p[stride] + fu * (p[stride + 1] - p[stride]);
    const float s = top + fv * (bottom - top);
    sums.rs += ref[k] * s;
    sums.s += s;
    sums.ss += s * s;
  }
  return sums;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define RECONDUIT_PATCH_MATCH_AVX2 1

float HorizontalSum(__m256 v) __attribute__((target("avx2,fma")));
float HorizontalSum(__m256 v) {
  const __m128 quad = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  const __m128 pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
  return _mm_cvtss_f32(_mm_add_ss(pair, _mm_shuffle_ps(pair, pair, 1)));
}

// The 8 bytes at pairs + 4 index[i] bytes for i = 0..3: two adjacent floats per index. (The
// masked form: GCC 12 warns that the unmasked one reads an undefined register.)
__m256 GatherPairs(const double* pairs, __m128i index) __attribute__((target("avx2,fma")));
__m256 GatherPairs(const double* pairs, __m128i index) {
  const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  return _mm256_castpd_ps(_mm256_mask_i32gather_pd(_mm256_setzero_pd(), pairs, index, all, 4));
}

// SumSamplesScalar, 8 samples at a time with AVX2 gathers (chosen at run time when the CPU has
// AVX2 and FMA: the default build targets baseline x86-64).
SampleSums SumSamplesAvx2(const float* base,
                          std::size_t stride,
                          const AffineWindow& w,
                          const WindowLayout& layout,
                          const float* ref) __attribute__((target("avx2,fma")));
SampleSums SumSamplesAvx2(const float* base,
                          std::size_t stride,
                          const AffineWindow& w,
                          const WindowLayout& layout,
                          const float* ref) {
  const __m256 uc = _mm256_set1_ps(w.uc), vc = _mm256_set1_ps(w.vc);
  const __m256 ux = _mm256_set1_ps(w.ux), uy = _mm256_set1_ps(w.uy);
  const __m256 vx = _mm256_set1_ps(w.vx), vy = _mm256_set1_ps(w.vy);
  const __m256i row = _mm256_set1_epi32(static_cast<int>(stride));
  const double* above_pairs = reinterpret_cast<const double*>(base);
  const double* below_pairs = reinterpret_cast<const double*>(base + stride);
  const __m256i order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);
  __m256 rs = _mm256_setzero_ps(), sum = _mm256_setzero_ps(), ss = _mm256_setzero_ps();
  for (int k = 0; k < layout.padded; k += 8) {
    const __m256 dx = _mm256_loadu_ps(&layout.dx[k]), dy = _mm256_loadu_ps(&layout.dy[k]);
    const __m256 u = _mm256_fmadd_ps(uy, dy, _mm256_fmadd_ps(ux, dx, uc));
    const __m256 v = _mm256_fmadd_ps(vy, dy, _mm256_fmadd_ps(vx, dx, vc));
    const __m256i iu = _mm256_cvttps_epi32(u), iv = _mm256_cvttps_epi32(v);
    const __m256 fu = _mm256_sub_ps(u, _mm256_cvtepi32_ps(iu));
    const __m256 fv = _mm256_sub_ps(v, _mm256_cvtepi32_ps(iv));
    // Each pixel's right neighbour is the next float: one 64-bit gather fetches both. Samples
    // 0, 1, 4, 5 go to the first gather and 2, 3, 6, 7 to the second, so that the in-lane
    // shuffles below put all eight back in order.
    const __m256i index =
        _mm256_permutevar8x32_epi32(_mm256_add_epi32(_mm256_mullo_epi32(iv, row), iu), order);
    const __m128i first = _mm256_castsi256_si128(index);
    const __m128i second = _mm256_extracti128_si256(index, 1);
    const __m256 top_a = GatherPairs(above_pairs, first);
    const __m256 top_b = GatherPairs(above_pairs, second);
    const __m256 bottom_a = GatherPairs(below_pairs, first);
    const __m256 bottom_b = GatherPairs(below_pairs, second);
    const __m256 p00 = _mm256_shuffle_ps(top_a, top_b, _MM_SHUFFLE(2, 0, 2, 0));
    const __m256 p01 = _mm256_shuffle_ps(top_a, top_b, _MM_SHUFFLE(3, 1, 3, 1));
    const __m256 p10 = _mm256_shuffle_ps(bottom_a, bottom_b, _MM_SHUFFLE(2, 0, 2, 0));
    const __m256 p11 = _mm256_shuffle_ps(bottom_a, bottom_b, _MM_SHUFFLE(3, 1, 3, 1));
    const __m256 top = _mm256_fmadd_ps(fu, _mm256_sub_ps(p01, p00), p00);
    const __m256 bottom = _mm256_fmadd_ps(fu, _mm256_sub_ps(p11, p10), p10);
    const __m256 s = _mm256_mul_ps(_mm256_fmadd_ps(fv, _mm256_sub_ps(bottom, top), top),
                                   _mm256_loadu_ps(&layout.weight[k]));
    rs = _mm256_fmadd_ps(_mm256_loadu_ps(ref + k), s, rs);
    sum = _mm256_add_ps(sum, s);
    ss = _mm256_fmadd_ps(s, s, ss);
  }
  return {HorizontalSum(rs), HorizontalSum(sum), HorizontalSum(ss)};
}
#endif

using SumSamplesFunction = SampleSums (*)(
    const float*, std::size_t, const AffineWindow&, const WindowLayout&, const float*);

SumSamplesFunction ChooseSumSamples(bool use_simd) {
#ifdef RECONDUIT_PATCH_MATCH_AVX2
  if (use_simd && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
    return SumSamplesAvx2;
#else
  (void)use_simd;
#endif
  return SumSamplesScalar;
}

// Room for the largest window's samples (radius 15, step 1: 31^2 = 961), padded.
using WindowSamples = std::array<float, 968>;

// Every pixel's plane hypothesis and its cost, row-major; what one pyramid level hands to the
// next finer one.
struct Planes {
  int width = 0, height = 0;
  Eigen::Matrix3f k_inv;  // Of the reference camera at this level.
  std::vector<float> depth;
  std::vector<Eigen::Vector3f> normal;
  std::vector<float> cost;
  float noise_stddev = 0.0f;  // The reference's estimated noise at this level (grey levels).
};

class PatchMatcher {
 public:
  // `coarse`, when given, holds the planes of the same reference at half this resolution: they
  // start every pixel instead of random planes.
  PatchMatcher(const PatchMatchInput& input,
               const PatchMatchOptions& options,
               const Planes* coarse = nullptr)
      : input_(input), options_(options), coarse_(coarse) {
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
    for (int dy : offsets_) {
      for (int dx : offsets_) {
        layout_.dx.push_back(static_cast<float>(dx));
        layout_.dy.push_back(static_cast<float>(dy));
        layout_.weight.push_back(1.0f);
      }
    }
    layout_.count = static_cast<int>(layout_.dx.size());
    layout_.padded = (layout_.count + 7) / 8 * 8;
    layout_.dx.resize(layout_.padded, 0.0f);
    layout_.dy.resize(layout_.padded, 0.0f);
    layout_.weight.resize(layout_.padded, 0.0f);
    min_inv_depth_ = static_cast<float>(1.0 / input.max_depth);
    max_inv_depth_ = static_cast<float>(1.0 / input.min_depth);
    cos_max_normal_angle_ =
        static_cast<float>(std::cos(options.max_normal_angle_deg * std::numbers::pi / 180.0));
    top_k_ = std::min<int>(options.top_k, static_cast<int>(sources_.size()));
  }

  // Runs `num_iterations` sweeps; refinement's perturbations are those of iteration
  // `first_iteration` onwards (halving each iteration).
  Planes Run(const CancelToken& cancel, int num_iterations, int first_iteration) {
    ComputeWindowStats();
    Initialize();
    for (int iteration = first_iteration; iteration < first_iteration + num_iterations;
         ++iteration) {
      for (int colour = 0; colour < 2; ++colour) {
        cancel.ThrowIfCanceled();
        ParallelFor(
            0, static_cast<std::size_t>(height_),
            [&](std::size_t row) { SweepRow(static_cast<int>(row), colour, iteration); },
            options_.num_threads);
      }
    }
    Planes planes;
    planes.width = width_;
    planes.height = height_;
    planes.k_inv = k_inv_;
    planes.depth = std::move(depth_);
    planes.normal = std::move(normal_);
    planes.cost = std::move(cost_);
    planes.noise_stddev = noise_stddev_;
    return planes;
  }

 private:
  // The ray through pixel (x, y) at depth z = 1.
  Eigen::Vector3f Ray(float x, float y) const { return k_inv_ * Eigen::Vector3f(x, y, 1.0f); }

  // The reference's window samples at (x, y), in layout_'s order, zero-padded.
  void ReferenceSamples(int x, int y, float* out) const {
    const cv::Mat& gray = input_.reference->gray;
    int k = 0;
    for (int dy : offsets_) {
      const float* line = gray.ptr<float>(y + dy) + x;
      for (int dx : offsets_) out[k++] = line[dx];
    }
    std::fill(out + k, out + layout_.padded, 0.0f);
  }

  bool Textured(int x, int y) const { return stats_.inv_norm.at<float>(y, x) > 0.0f; }

  void ComputeWindowStats() {
    const cv::Mat& gray = input_.reference->gray;
    stats_.mean = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(0));
    stats_.inv_norm = cv::Mat(height_, width_, CV_32FC1, cv::Scalar(0));
    // Texture must stand out of the photo's own noise (core/mvs/image_noise.h); the estimate
    // is taken at each pyramid level, where averaging has lowered the noise.
    noise_stddev_ =
        options_.noise_texture_factor > 0.0 ? static_cast<float>(EstimateNoiseStddev(gray)) : 0.0f;
    const float min_stddev =
        std::max(static_cast<float>(options_.min_texture_stddev),
                 static_cast<float>(options_.noise_texture_factor) * noise_stddev_);
    const float min_norm = min_stddev * std::sqrt(num_samples_);
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
  // The samples are summed by an AVX2 kernel when the CPU has AVX2 (benchmark at 768 x 512,
  // default options, 1 thread, CPU seconds: portable loop 6.0 s, AVX2 with one 32-bit gather
  // per bilinear corner 4.4-5.9 s, with one 64-bit gather per pair of corners 3.3-3.5 s).
  float SourceCost(
      int x, int y, const Eigen::Matrix3f& H, const cv::Mat& src, const float* ref) const {
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
    const SampleSums sums =
        sum_samples_(src.ptr<float>(0), src.step1(), {uc, vc, ux, uy, vx, vy}, layout_, ref);
    const float sum_rs = sums.rs, sum_s = sums.s, sum_ss = sums.ss;
    const float var_s = sum_ss - sum_s * sum_s / num_samples_;
    if (var_s <= 1e-6f) return kEmptyCost;
    const float mean_r = stats_.mean.at<float>(y, x);
    const float ncc =
        (sum_rs - mean_r * sum_s) * stats_.inv_norm.at<float>(y, x) / std::sqrt(var_s);
    return std::clamp(1.0f - ncc, 0.0f, kEmptyCost);
  }

  // The multi-view cost of the plane (depth, normal) at pixel (x, y).
  float Cost(int x, int y, float depth, const Eigen::Vector3f& normal, const float* ref) const {
    const Eigen::Vector3f point = depth * Ray(static_cast<float>(x), static_cast<float>(y));
    const float delta = -normal.dot(point);
    if (delta <= 0.0f) return kEmptyCost;
    const Eigen::Vector3f m = k_inv_.transpose() * normal / delta;
    std::array<float, 16> costs;
    const int n = std::min<int>(static_cast<int>(sources_.size()), 16);
    for (int s = 0; s < n; ++s) {
      const Eigen::Matrix3f H = sources_[s].A - sources_[s].b * m.transpose();
      costs[s] = SourceCost(x, y, H, *sources_[s].gray, ref);
    }
    std::partial_sort(costs.begin(), costs.begin() + top_k_, costs.begin() + n);
    // Sources whose window leaves their image (kEmptyCost) do not count: near the border of
    // the reference, often one source sees the surface. Then the mean of those that do, with
    // kSingleSourcePenalty per missing source, so that more support wins between hypotheses.
    float sum = 0.0f;
    int valid = 0;
    for (int k = 0; k < top_k_; ++k) {
      if (costs[k] >= kEmptyCost) break;
      sum += costs[k];
      ++valid;
    }
    if (valid == 0) return kEmptyCost;
    return sum / static_cast<float>(valid) + kMissingSourcePenalty * (top_k_ - valid);
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

  // The coarse level's plane at the pixel under (x, y), intersected with (x, y)'s ray; false
  // when there is none (no coarse level, or its plane misses the depth range).
  bool UpsampledPlane(int x, int y, float* depth, Eigen::Vector3f* normal) const {
    if (coarse_ == nullptr) return false;
    // Coarse pixel i covers fine pixels 2i and 2i + 1 (see HalveView).
    const int xc = std::clamp(x / 2, 0, coarse_->width - 1);
    const int yc = std::clamp(y / 2, 0, coarse_->height - 1);
    const std::size_t j = static_cast<std::size_t>(yc) * coarse_->width + xc;
    if (coarse_->cost[j] >= kEmptyCost) return false;
    const Eigen::Vector3f& n = coarse_->normal[j];
    const Eigen::Vector3f point =
        coarse_->depth[j] *
        (coarse_->k_inv * Eigen::Vector3f(static_cast<float>(xc), static_cast<float>(yc), 1.0f));
    const float denom = n.dot(Ray(static_cast<float>(x), static_cast<float>(y)));
    if (std::abs(denom) < 1e-6f) return false;
    *depth = n.dot(point) / denom;
    *normal = n;
    return InDepthRange(*depth);
  }

  void Initialize() {
    const std::size_t n = static_cast<std::size_t>(width_) * height_;
    depth_.assign(n, 0.0f);
    normal_.assign(n, Eigen::Vector3f(0, 0, -1));
    cost_.assign(n, kEmptyCost);
    ParallelFor(
        0, static_cast<std::size_t>(height_),
        [&](std::size_t row) {
          const int y = static_cast<int>(row);
          for (int x = 0; x < width_; ++x) {
            if (!Inside(x, y) || !Textured(x, y)) continue;
            const std::size_t i = Index(x, y);
            if (!UpsampledPlane(x, y, &depth_[i], &normal_[i])) {
              PixelRandom random(options_.seed, i, 0);
              const Eigen::Vector3f ray =
                  Ray(static_cast<float>(x), static_cast<float>(y)).normalized();
              depth_[i] = RandomDepth(random);
              normal_[i] = RandomNormal(random, ray);
            }
            WindowSamples ref;
            ReferenceSamples(x, y, ref.data());
            cost_[i] = Cost(x, y, depth_[i], normal_[i], ref.data());
          }
        },
        options_.num_threads);
    // A sparse point says where the surface is, not how it is tilted: fronto-parallel, kept
    // when it beats the start plane.
    for (const DepthSeed& seed : input_.seeds) {
      const int x = static_cast<int>(std::lround(seed.pixel.x()));
      const int y = static_cast<int>(std::lround(seed.pixel.y()));
      if (!Inside(x, y) || !Textured(x, y)) continue;
      const Eigen::Vector3f ray_unit =
          Ray(static_cast<float>(x), static_cast<float>(y)).normalized();
      WindowSamples ref;
      ReferenceSamples(x, y, ref.data());
      TryPlane(x, y, static_cast<float>(seed.depth), Eigen::Vector3f(0.0f, 0.0f, -1.0f), ray_unit,
               ref.data());
    }
  }

  bool Inside(int x, int y) const {
    const int r = options_.window_radius;
    return x >= r && y >= r && x < width_ - r && y < height_ - r;
  }

  // Keeps (depth, normal) at pixel i if it costs less than what is there.
  void TryPlane(int x,
                int y,
                float depth,
                const Eigen::Vector3f& normal,
                const Eigen::Vector3f& ray_unit,
                const float* ref) {
    if (!InDepthRange(depth) || !AcceptableNormal(normal, ray_unit)) return;
    const std::size_t i = Index(x, y);
    const float cost = Cost(x, y, depth, normal, ref);
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
      WindowSamples window;
      ReferenceSamples(x, y, window.data());
      const float* ref = window.data();
      // Propagation: the neighbour's plane, intersected with this pixel's ray.
      for (std::size_t k = coarse_ ? 4 : 0; k < kNeighbors.size(); ++k) {
        const auto& [dx, dy] = kNeighbors[k];
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
        TryPlane(x, y, depth, n, ray_unit, ref);
      }
      Refine(x, y, iteration, ray_unit, ref);
    }
  }

  // Random changes of the pixel's plane: a new depth, a new normal, and perturbations of both
  // whose size halves with each iteration (from +-4 % of the depth and about +-15 degrees),
  // plus a ten times finer depth step, so that the last iterations polish to well under a
  // thousandth of the depth.
  void Refine(int x, int y, int iteration, const Eigen::Vector3f& ray_unit, const float* ref) {
    const std::size_t i = Index(x, y);
    PixelRandom random(options_.seed, i, static_cast<std::uint64_t>(iteration) + 1);
    const float scale = std::pow(0.5f, static_cast<float>(iteration));
    if (coarse_ == nullptr) {
      TryPlane(x, y, RandomDepth(random), normal_[i], ray_unit, ref);
      TryPlane(x, y, depth_[i], RandomNormal(random, ray_unit), ray_unit, ref);
    }
    auto centred = [&random] { return 2.0f * random.Uniform() - 1.0f; };
    Eigen::Vector3f perturbed =
        normal_[i] + 0.25f * scale * Eigen::Vector3f(centred(), centred(), centred());
    perturbed.normalize();
    TryPlane(x, y, depth_[i] * (1.0f + 0.04f * scale * centred()), perturbed, ray_unit, ref);
    TryPlane(x, y, depth_[i] * (1.0f + 0.004f * scale * centred()), normal_[i], ray_unit, ref);
  }

  const PatchMatchInput& input_;
  const PatchMatchOptions& options_;
  const Planes* coarse_ = nullptr;
  int width_ = 0, height_ = 0;
  Eigen::Matrix3f k_inv_;
  std::vector<SourceMapping> sources_;
  std::vector<int> offsets_;
  WindowLayout layout_;
  SumSamplesFunction sum_samples_ = ChooseSumSamples(options_.use_simd);
  float num_samples_ = 0.0f;
  float min_inv_depth_ = 0.0f, max_inv_depth_ = 0.0f;
  float cos_max_normal_angle_ = 0.0f;
  int top_k_ = 1;
  WindowStats stats_;
  float noise_stddev_ = 0.0f;
  std::vector<float> depth_;
  std::vector<Eigen::Vector3f> normal_;
  std::vector<float> cost_;
};

// The depth map of `planes`: pixels costing more than `max_cost` left empty.
DepthMap Finish(const Planes& planes, double max_cost) {
  DepthMap map;
  map.noise_stddev = planes.noise_stddev;
  map.depth = cv::Mat(planes.height, planes.width, CV_32FC1, cv::Scalar(0));
  map.normal = cv::Mat(planes.height, planes.width, CV_32FC3, cv::Scalar(0, 0, 0));
  map.cost = cv::Mat(planes.height, planes.width, CV_32FC1, cv::Scalar(kEmptyCost));
  for (int y = 0; y < planes.height; ++y) {
    for (int x = 0; x < planes.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * planes.width + x;
      if (planes.cost[i] > max_cost) continue;
      const Eigen::Vector3f& n = planes.normal[i];
      map.depth.at<float>(y, x) = planes.depth[i];
      map.normal.at<cv::Vec3f>(y, x) = {n.x(), n.y(), n.z()};
      map.cost.at<float>(y, x) = planes.cost[i];
    }
  }
  return map;
}

// `view` at half its resolution: an even-sized crop averaged over 2 x 2 pixels, so coarse pixel
// i covers pixels 2i and 2i + 1, centred at 2i + 0.5 (pixel centres at integers).
MvsView HalveView(const MvsView& view) {
  MvsView half;
  const int width = view.gray.cols / 2, height = view.gray.rows / 2;
  cv::resize(view.gray(cv::Rect(0, 0, 2 * width, 2 * height)), half.gray, cv::Size(width, height),
             0.0, 0.0, cv::INTER_AREA);
  half.camera = view.camera;
  half.camera.width = width;
  half.camera.height = height;
  half.camera.focal = view.camera.focal / 2.0;
  half.camera.cx = (view.camera.cx - 0.5) / 2.0;
  half.camera.cy = (view.camera.cy - 0.5) / 2.0;
  half.cam_from_world = view.cam_from_world;
  return half;
}

// PatchMatch over `levels` halvings below `input`'s resolution, coarsest first: the coarsest
// level runs options.num_iterations sweeps from random planes, each finer one
// options.upsampled_iterations sweeps from the planes of the level below.
Planes RunPyramid(const PatchMatchInput& input,
                  const PatchMatchOptions& options,
                  int levels,
                  const CancelToken& cancel) {
  // No level whose photos would be smaller than two windows across.
  int smallest_side = std::min(input.reference->gray.cols, input.reference->gray.rows);
  for (const MvsView* source : input.sources)
    smallest_side = std::min({smallest_side, source->gray.cols, source->gray.rows});
  if (levels == 0 || smallest_side / 2 < 2 * (2 * options.window_radius + 1))
    return PatchMatcher(input, options).Run(cancel, options.num_iterations, 0);
  std::vector<MvsView> halves;
  halves.reserve(input.sources.size() + 1);
  halves.push_back(HalveView(*input.reference));
  for (const MvsView* source : input.sources) halves.push_back(HalveView(*source));
  PatchMatchInput coarse_input = input;
  coarse_input.reference = &halves[0];
  for (std::size_t s = 0; s < input.sources.size(); ++s) coarse_input.sources[s] = &halves[s + 1];
  for (DepthSeed& seed : coarse_input.seeds) seed.pixel = (seed.pixel.array() - 0.5) / 2.0;
  const Planes coarse = RunPyramid(coarse_input, options, levels - 1, cancel);
  return PatchMatcher(input, options, &coarse)
      .Run(cancel, options.upsampled_iterations, options.upsampled_first_iteration);
}

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
  } else if (pyramid_levels < 0 || pyramid_levels > 4) {
    m << "pyramid_levels must be in [0, 4], got " << pyramid_levels;
  } else if (upsampled_iterations < 1 || upsampled_iterations > 50) {
    m << "upsampled_iterations must be in [1, 50], got " << upsampled_iterations;
  } else if (upsampled_first_iteration < 0 || upsampled_first_iteration > 50) {
    m << "upsampled_first_iteration must be in [0, 50], got " << upsampled_first_iteration;
  } else if (top_k < 1 || top_k > 16) {
    m << "top_k must be in [1, 16], got " << top_k;
  } else if (!(min_texture_stddev >= 0.0)) {
    m << "min_texture_stddev must be >= 0, got " << min_texture_stddev;
  } else if (!(noise_texture_factor >= 0.0)) {
    m << "noise_texture_factor must be >= 0, got " << noise_texture_factor;
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
  return Finish(RunPyramid(input, options, options.pyramid_levels, cancel), options.max_cost);
}

}  // namespace reconduit
