#include "core/scene/procedural_texture.h"

#include <gtest/gtest.h>

#include <random>
#include <set>
#include <string>

namespace reconduit {
namespace {

TEST(ProceduralTexture, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(ProceduralTexture().Check(&error)) << error;
}

TEST(ProceduralTexture, CheckRejectsBadOptions) {
  std::string error;
  ProceduralTexture texture;
  texture.cell_size = 0.0;
  EXPECT_FALSE(texture.Check(&error));
  EXPECT_NE(error.find("cell_size"), std::string::npos) << error;
  texture = ProceduralTexture();
  texture.num_layers = 9;
  EXPECT_FALSE(texture.Check(&error));
  EXPECT_NE(error.find("num_layers"), std::string::npos) << error;
  texture = ProceduralTexture();
  texture.shape_probability = -0.1;
  EXPECT_FALSE(texture.Check(&error));
  EXPECT_NE(error.find("shape_probability"), std::string::npos) << error;
  texture = ProceduralTexture();
  texture.base_color.y() = 256.0;
  EXPECT_FALSE(texture.Check(&error));
  EXPECT_NE(error.find("base_color"), std::string::npos) << error;
  texture = ProceduralTexture();
  texture.noise_amplitude = -1.0;
  EXPECT_FALSE(texture.Check(&error));
  EXPECT_NE(error.find("noise_amplitude"), std::string::npos) << error;
}

TEST(ProceduralTexture, PlainTextureIsBaseColour) {
  ProceduralTexture texture;
  texture.num_layers = 0;
  texture.noise_amplitude = 0.0;
  texture.base_color = {10.0, 20.0, 30.0};
  EXPECT_EQ(EvaluateTexture(texture, 0.3, -7.1), Eigen::Vector3d(10.0, 20.0, 30.0));
  EXPECT_EQ(EvaluateTexture(texture, 1e4, 2.5), Eigen::Vector3d(10.0, 20.0, 30.0));
}

TEST(ProceduralTexture, DeterministicInRangeAndSeedDependent) {
  ProceduralTexture a, b;
  b.seed = 1;
  std::mt19937_64 rng(0);
  std::uniform_real_distribution<double> coordinate(-20.0, 20.0);
  double difference = 0.0;
  constexpr int kSamples = 2000;
  for (int i = 0; i < kSamples; ++i) {
    const double u = coordinate(rng), v = coordinate(rng);
    const Eigen::Vector3d color = EvaluateTexture(a, u, v);
    EXPECT_EQ(color, EvaluateTexture(a, u, v));
    EXPECT_TRUE((color.array() >= 0.0).all() && (color.array() <= 255.0).all()) << color;
    difference += (color - EvaluateTexture(b, u, v)).cwiseAbs().mean();
  }
  EXPECT_GT(difference / kSamples, 30.0);
}

// The contrast between points `step` metres apart, averaged over many random pairs.
double MeanContrastAtStep(const ProceduralTexture& texture, double step) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> coordinate(0.0, 10.0);
  double sum = 0.0;
  constexpr int kSamples = 4000;
  for (int i = 0; i < kSamples; ++i) {
    const double u = coordinate(rng), v = coordinate(rng);
    sum += (EvaluateTexture(texture, u, v) - EvaluateTexture(texture, u + step, v)).norm();
  }
  return sum / kSamples;
}

TEST(ProceduralTexture, HasContrastAtEveryScale) {
  // The default texture (cells of 0.4 m down to 0.05 m) changes noticeably between points
  // 2 cm apart as well as 30 cm apart.
  const ProceduralTexture texture;
  EXPECT_GT(MeanContrastAtStep(texture, 0.02), 20.0);
  EXPECT_GT(MeanContrastAtStep(texture, 0.3), 100.0);
  // Without shapes, the smooth noise alone has little contrast at 2 cm.
  ProceduralTexture noise_only = texture;
  noise_only.num_layers = 0;
  EXPECT_LT(MeanContrastAtStep(noise_only, 0.02), 10.0);
}

TEST(ProceduralTexture, ShapeEdgesAreSoft) {
  // The edge ramps over 8 % of the finest cell (4 mm by default), so points 0.1 mm apart
  // differ by at most ~255 * 0.1 / 4 per channel plus the noise's slope.
  const ProceduralTexture texture;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coordinate(0.0, 5.0);
  double max_step = 0.0;
  for (int i = 0; i < 20000; ++i) {
    const double u = coordinate(rng), v = coordinate(rng);
    max_step = std::max(
        max_step, (EvaluateTexture(texture, u, v) - EvaluateTexture(texture, u + 1e-4, v + 1e-4))
                      .cwiseAbs()
                      .maxCoeff());
  }
  EXPECT_LT(max_step, 12.0);
  EXPECT_GT(max_step, 1.0);  // But they are edges.
}

TEST(ProceduralTexture, ShapeProbabilityControlsCoverage) {
  ProceduralTexture none;
  none.shape_probability = 0.0;
  ProceduralTexture plain = none;
  plain.num_layers = 0;
  ProceduralTexture full = none;
  full.shape_probability = 1.0;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> coordinate(-5.0, 5.0);
  int covered = 0;
  constexpr int kSamples = 2000;
  for (int i = 0; i < kSamples; ++i) {
    const double u = coordinate(rng), v = coordinate(rng);
    EXPECT_EQ(EvaluateTexture(none, u, v), EvaluateTexture(plain, u, v));
    covered += EvaluateTexture(full, u, v) != EvaluateTexture(plain, u, v);
  }
  EXPECT_GT(covered, 0.6 * kSamples);
}

}  // namespace
}  // namespace reconduit
