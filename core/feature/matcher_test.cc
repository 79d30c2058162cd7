#include "core/feature/matcher.h"

#include "core/util/timer.h"

#include <gtest/gtest.h>

#include <random>

namespace reconduit {
namespace {

DescriptorMatrix RandomUnitRows(int n, std::mt19937& rng) {
  std::normal_distribution<float> normal;
  DescriptorMatrix m(n, 128);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < 128; ++c) m(r, c) = std::abs(normal(rng));
    m.row(r).normalize();
  }
  return m;
}

// Straightforward reference: the same rules, one distance at a time.
std::vector<FeatureMatch> NaiveMatch(const DescriptorMatrix& a,
                                     const DescriptorMatrix& b,
                                     const MatchingOptions& o) {
  auto nearest = [](const DescriptorMatrix& from, int i, const DescriptorMatrix& to, double* d1,
                    double* d2) {
    int best = -1;
    *d1 = *d2 = 1e30;
    for (int j = 0; j < to.rows(); ++j) {
      const double d = (from.row(i) - to.row(j)).squaredNorm();
      if (d < *d1) {
        *d2 = *d1;
        *d1 = d;
        best = j;
      } else if (d < *d2) {
        *d2 = d;
      }
    }
    return best;
  };
  std::vector<FeatureMatch> matches;
  for (int i = 0; i < a.rows(); ++i) {
    double d1, d2, e1, e2;
    const int j = nearest(a, i, b, &d1, &d2);
    if (j < 0 || std::sqrt(d1) > o.max_distance || std::sqrt(d1) >= o.max_ratio * std::sqrt(d2)) {
      continue;
    }
    if (o.cross_check && nearest(b, j, a, &e1, &e2) != i) continue;
    matches.push_back({i, j});
  }
  return matches;
}

TEST(MatchingOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(MatchingOptions().Check(&error)) << error;
  MatchingOptions bad;
  bad.max_ratio = 0;
  EXPECT_FALSE(bad.Check(&error));
}

TEST(MatchDescriptors, FindsNoisyCopiesAndRejectsAmbiguousOnes) {
  std::mt19937 rng(5);
  const DescriptorMatrix b = RandomUnitRows(3000, rng);  // More than one block of rows.
  // a: noisy copies of b's first 1500 rows, in reverse order, then 500 unrelated rows.
  DescriptorMatrix a(2000, 128);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  for (int i = 0; i < 1500; ++i) {
    a.row(i) = b.row(1499 - i);
    for (int c = 0; c < 128; ++c) a(i, c) += noise(rng);
    a.row(i).normalize();
  }
  a.bottomRows(500) = RandomUnitRows(500, rng);
  // Make b's row 0 ambiguous: a near-duplicate of it appears at row 2999.
  DescriptorMatrix b2 = b;
  b2.row(2999) = b.row(0);
  b2(2999, 0) += 0.001f;
  b2.row(2999).normalize();

  const std::vector<FeatureMatch> matches = MatchDescriptors(a, b2, MatchingOptions());
  int correct = 0;
  for (const FeatureMatch& m : matches) {
    EXPECT_NE(m.index2, 2999);
    EXPECT_NE(m.index2, 0) << "ambiguous: fails the ratio test";
    if (m.index1 < 1500 && m.index2 == 1499 - m.index1) ++correct;
  }
  EXPECT_EQ(correct, 1499) << "every unambiguous copy is found";
  EXPECT_EQ(static_cast<int>(matches.size()), correct) << "random rows find no partner";
}

TEST(MatchDescriptors, AgreesWithNaiveReference) {
  std::mt19937 rng(9);
  // Correlated random descriptors so that the ratio and distance tests both bite.
  const DescriptorMatrix base = RandomUnitRows(300, rng);
  DescriptorMatrix a(400, 128), b(350, 128);
  std::uniform_int_distribution<int> pick(0, 299);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (int i = 0; i < 400; ++i) {
    a.row(i) = base.row(pick(rng));
    for (int c = 0; c < 128; ++c) a(i, c) += noise(rng);
    a.row(i).normalize();
  }
  for (int i = 0; i < 350; ++i) {
    b.row(i) = base.row(pick(rng));
    for (int c = 0; c < 128; ++c) b(i, c) += noise(rng);
    b.row(i).normalize();
  }
  for (bool cross_check : {true, false}) {
    MatchingOptions options;
    options.cross_check = cross_check;
    const auto fast = MatchDescriptors(a, b, options);
    const auto slow = NaiveMatch(a, b, options);
    ASSERT_EQ(fast.size(), slow.size()) << "cross_check=" << cross_check;
    ASSERT_GT(fast.size(), 20u);
    for (std::size_t k = 0; k < fast.size(); ++k) {
      EXPECT_EQ(fast[k].index1, slow[k].index1);
      EXPECT_EQ(fast[k].index2, slow[k].index2);
    }
  }
}

TEST(MatchDescriptors, EmptyInputGivesNoMatches) {
  std::mt19937 rng(1);
  EXPECT_TRUE(MatchDescriptors(DescriptorMatrix(0, 128), RandomUnitRows(5, rng), {}).empty());
  EXPECT_TRUE(MatchDescriptors(RandomUnitRows(5, rng), DescriptorMatrix(0, 128), {}).empty());
}

TEST(ToDescriptorMatrix, RowsHaveUnitNorm) {
  FeatureSet features;
  features.keypoints.resize(2);
  features.descriptors = cv::Mat(2, 128, CV_8U, cv::Scalar(7));
  features.descriptors.at<std::uint8_t>(1, 3) = 200;
  const DescriptorMatrix m = ToDescriptorMatrix(features);
  EXPECT_NEAR(m.row(0).norm(), 1.0f, 1e-6f);
  EXPECT_NEAR(m.row(1).norm(), 1.0f, 1e-6f);
}

}  // namespace
}  // namespace reconduit
