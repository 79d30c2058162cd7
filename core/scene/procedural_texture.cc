#include "core/scene/procedural_texture.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace reconduit {
namespace {

// SplitMix64's finaliser: a cheap, well-mixed 64-bit hash.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Hash of a lattice cell (i, j) of one layer; `layer_key` = LayerKey(seed, layer). One mixing
// round over a linear combination of the indices keeps this cheap: it runs ~30 times per
// texture evaluation.
std::uint64_t LayerKey(std::uint64_t seed, std::uint64_t layer) { return Mix(seed ^ Mix(layer)); }
std::uint64_t CellHash(std::uint64_t layer_key, std::int64_t i, std::int64_t j) {
  return Mix(layer_key + static_cast<std::uint64_t>(i) * 0x9e3779b97f4a7c15ULL +
             static_cast<std::uint64_t>(j) * 0xc2b2ae3d27d4eb4fULL);
}

// Bits [shift, shift + 16) of a hash as a number in [0, 1).
double Unit(std::uint64_t hash, int shift) {
  return static_cast<double>((hash >> shift) & 0xffff) / 65536.0;
}

double SmoothStep(double t) { return t * t * (3.0 - 2.0 * t); }

// Value noise in [0, 1]: hashed values on the integer lattice, interpolated with smoothstep.
double ValueNoise(std::uint64_t layer_key, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto i = static_cast<std::int64_t>(fx);
  const auto j = static_cast<std::int64_t>(fy);
  const double sx = SmoothStep(x - fx), sy = SmoothStep(y - fy);
  const double v00 = Unit(CellHash(layer_key, i, j), 0);
  const double v10 = Unit(CellHash(layer_key, i + 1, j), 0);
  const double v01 = Unit(CellHash(layer_key, i, j + 1), 0);
  const double v11 = Unit(CellHash(layer_key, i + 1, j + 1), 0);
  const double top = v00 + sx * (v10 - v00);
  const double bottom = v01 + sx * (v11 - v01);
  return top + sy * (bottom - top);
}

// (cos, sin) of kNumAngles rectangle orientations evenly spread over [0, pi).
constexpr int kNumAngles = 64;
const std::array<Eigen::Vector2d, kNumAngles>& Orientations() {
  static const std::array<Eigen::Vector2d, kNumAngles> orientations = [] {
    std::array<Eigen::Vector2d, kNumAngles> result;
    for (int k = 0; k < kNumAngles; ++k) {
      const double angle = M_PI * k / kNumAngles;
      result[k] = {std::cos(angle), std::sin(angle)};
    }
    return result;
  }();
  return orientations;
}

// Layer ids for the hash, so noise octaves and shape layers are independent.
constexpr std::uint64_t kNoiseLayerBase = 100;
constexpr std::uint64_t kShapeLayerBase = 200;
constexpr std::uint64_t kColorSalt = 0x5851f42d4c957f2dULL;
constexpr int kNumNoiseOctaves = 3;
// Shapes are centred within kCenterJitter of their cell's middle, with radius in
// [kMinRadius, kMinRadius + kRadiusRange) cells; a rectangle's corner is at most sqrt(2)
// radius from its centre. So a shape reaches at most kCenterJitter + sqrt(2) * 0.5 + edge / 2
// < 1 cell from its cell's middle, and a point only needs the 2 x 2 cells whose middles are
// nearest to it.
constexpr double kCenterJitter = 0.25;
constexpr double kMinRadius = 0.15;
constexpr double kRadiusRange = 0.35;
// Width of the soft edge, in cells.
constexpr double kEdgeWidth = 0.08;
static_assert(kCenterJitter + 1.4143 * (kMinRadius + kRadiusRange) + 0.5 * kEdgeWidth <= 1.0);

}  // namespace

bool ProceduralTexture::Check(std::string* error) const {
  std::ostringstream message;
  if (!std::isfinite(cell_size) || cell_size <= 0.0) {
    message << "cell_size must be positive, got " << cell_size;
  } else if (num_layers < 0 || num_layers > 8) {
    message << "num_layers must be in [0, 8], got " << num_layers;
  } else if (!(shape_probability >= 0.0 && shape_probability <= 1.0)) {
    message << "shape_probability must be in [0, 1], got " << shape_probability;
  } else if (!(base_color.array() >= 0.0).all() || !(base_color.array() <= 255.0).all()) {
    message << "base_color channels must be in [0, 255]";
  } else if (!std::isfinite(noise_amplitude) || noise_amplitude < 0.0) {
    message << "noise_amplitude must be >= 0, got " << noise_amplitude;
  } else {
    return true;
  }
  if (error != nullptr) *error = message.str();
  return false;
}

Eigen::Vector3d EvaluateTexture(const ProceduralTexture& texture, double u, double v) {
  // Background: octaves of value noise from twice the coarsest cell size down, each at half
  // the amplitude of the previous, normalised to [-1, 1].
  double noise = 0.0, amplitude = 1.0, total = 0.0, scale = 0.5 / texture.cell_size;
  for (int octave = 0; octave < kNumNoiseOctaves; ++octave) {
    noise += amplitude *
             ValueNoise(LayerKey(texture.seed, kNoiseLayerBase + octave), u * scale, v * scale);
    total += amplitude;
    amplitude *= 0.5;
    scale *= 2.0;
  }
  noise = 2.0 * noise / total - 1.0;
  Eigen::Vector3d color =
      (texture.base_color.array() + texture.noise_amplitude * noise).cwiseMax(0.0).cwiseMin(255.0);

  // Shapes, coarse layers first so that finer ones paint over them. Within a layer, cells are
  // painted in increasing (j, i) order whichever 2 x 2 block is visited, so overlapping shapes
  // stack the same way on both sides of a block boundary.
  double cell = texture.cell_size;
  const auto presence_threshold = static_cast<std::uint64_t>(texture.shape_probability * 65536.0);
  for (int layer = 0; layer < texture.num_layers; ++layer, cell *= 0.5) {
    const std::uint64_t layer_key = LayerKey(texture.seed, kShapeLayerBase + layer);
    const double x = u / cell, y = v / cell;  // Position in cells.
    const auto i0 = static_cast<std::int64_t>(std::floor(x - 0.5));
    const auto j0 = static_cast<std::int64_t>(std::floor(y - 0.5));
    for (std::int64_t j = j0; j <= j0 + 1; ++j) {
      for (std::int64_t i = i0; i <= i0 + 1; ++i) {
        const std::uint64_t h = CellHash(layer_key, i, j);
        if ((h & 0xffff) >= presence_threshold) continue;
        const double dx =
            x - (static_cast<double>(i) + 0.5 + kCenterJitter * (2.0 * Unit(h, 16) - 1.0));
        const double dy =
            y - (static_cast<double>(j) + 0.5 + kCenterJitter * (2.0 * Unit(h, 32) - 1.0));
        const double radius = kMinRadius + kRadiusRange * Unit(h, 48);
        // Signed distance to the outline, in cells (negative inside).
        double distance;
        if ((h >> 63) == 0) {
          distance = std::sqrt(dx * dx + dy * dy) - radius;
        } else {
          // A rectangle with sides 2 radius and 2 aspect radius, rotated.
          const std::uint64_t h2 = Mix(h);
          const Eigen::Vector2d& cs = Orientations()[h2 % kNumAngles];
          const double aspect = 0.4 + 0.6 * Unit(h2, 16);
          const double bx = cs.x() * dx + cs.y() * dy, by = -cs.y() * dx + cs.x() * dy;
          distance = std::max(std::abs(bx) - radius, std::abs(by) - aspect * radius);
        }
        if (distance >= 0.5 * kEdgeWidth) continue;
        const double alpha = std::min(1.0, 0.5 - distance / kEdgeWidth);
        const std::uint64_t hc = Mix(h ^ kColorSalt);
        const Eigen::Vector3d shape_color(255.0 * Unit(hc, 0), 255.0 * Unit(hc, 16),
                                          255.0 * Unit(hc, 32));
        color += alpha * (shape_color - color);
      }
    }
  }
  return color;
}

}  // namespace reconduit
