#include "core/feature/matcher.h"

#include "core/util/timer.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <vector>

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

// Descriptors whose entries are multiples of 1/32 below 1: every product and sum of a squared
// distance is then exact in float, in whatever order sgemm, Eigen or a plain loop adds them, so
// equal distances are bit-equal in MatchDescriptors too and a reference can be compared exactly
// (ties included). Bases: six entries of 8/32 .. 16/32, the other 122 zero.
DescriptorMatrix GridBases(int n, std::mt19937& rng) {
  std::uniform_int_distribution<int> dim(0, 127), value(8, 16);
  DescriptorMatrix m = DescriptorMatrix::Zero(n, 128);
  for (int r = 0; r < n; ++r) {
    for (int k = 0; k < 6; ++k) m(r, dim(rng)) = static_cast<float>(value(rng)) / 32.0f;
  }
  return m;
}

// n rows, each a random base plus 0 .. max_steps steps of ±1/32 (0 steps: an exact duplicate).
DescriptorMatrix GridRows(const DescriptorMatrix& bases, int n, int max_steps, std::mt19937& rng) {
  std::uniform_int_distribution<int> base(0, static_cast<int>(bases.rows()) - 1), dim(0, 127),
      steps(0, max_steps), sign(0, 1);
  DescriptorMatrix m(n, 128);
  for (int r = 0; r < n; ++r) {
    m.row(r) = bases.row(base(rng));
    for (int s = steps(rng); s > 0; --s) m(r, dim(rng)) += sign(rng) ? 1.0f / 32 : -1.0f / 32;
  }
  return m;
}

// All squared distances, row-major n1 x n2; exact for GridRows descriptors.
std::vector<float> SquaredDistances(const DescriptorMatrix& a, const DescriptorMatrix& b) {
  std::vector<float> d;
  d.reserve(static_cast<std::size_t>(a.rows()) * b.rows());
  for (int i = 0; i < a.rows(); ++i) {
    for (int j = 0; j < b.rows(); ++j) d.push_back((a.row(i) - b.row(j)).squaredNorm());
  }
  return d;
}

// Brute force with MatchDescriptors' rules on exact squared distances: the nearest is the lowest
// index among equal distances, the second nearest the smallest distance of all the others (equal
// to the nearest's when it repeats, which fails any ratio test); the distance and ratio tests
// compare squared distances in float. Counts the ties the comparison depends on.
struct ReferenceTies {
  int repeated_minima = 0;  // Rows within max_distance whose smallest distance repeats.
  int column_ties = 0;      // Cross-checked matches whose column's smallest distance repeats.
};

std::vector<std::pair<int, int>> ReferenceMatch(
    const std::vector<float>& d, int n1, int n2, const MatchingOptions& o, ReferenceTies* ties) {
  const auto at = [&](int i, int j) { return d[static_cast<std::size_t>(i) * n2 + j]; };
  const float inf = std::numeric_limits<float>::infinity();
  const float max_distance2 = static_cast<float>(o.max_distance * o.max_distance);
  const float max_ratio2 = static_cast<float>(o.max_ratio * o.max_ratio);
  std::vector<std::pair<int, int>> matches;
  for (int i = 0; i < n1; ++i) {
    float d1 = inf;
    for (int j = 0; j < n2; ++j) d1 = std::min(d1, at(i, j));
    int nearest = 0;
    while (at(i, nearest) != d1) ++nearest;
    float d2 = inf;
    for (int j = 0; j < n2; ++j) {
      if (j != nearest) d2 = std::min(d2, at(i, j));
    }
    if (d1 > max_distance2) continue;
    if (d2 == d1) ++ties->repeated_minima;
    if (d1 >= max_ratio2 * d2) continue;
    float column_d1 = inf;
    for (int k = 0; k < n1; ++k) column_d1 = std::min(column_d1, at(k, nearest));
    int column_nearest = 0, column_count = 0;
    for (int k = n1 - 1; k >= 0; --k) {
      if (at(k, nearest) == column_d1) {
        column_nearest = k;
        ++column_count;
      }
    }
    if (o.cross_check) {
      if (column_nearest != i) continue;
      if (column_count > 1) ++ties->column_ties;
    }
    matches.emplace_back(i, nearest);
  }
  return matches;
}

// A size of the brute-force comparisons on GridRows descriptors.
struct GridCase {
  int n1, n2;
  int bases;      // Fewer bases: more exact duplicates, more ties.
  int max_steps;  // Steps of 1/32 away from the base.
};

TEST(MatchDescriptors, EqualsBruteForceExactlyWithTiesOddSizesAndSeveralBlocks) {
  // Tiny sizes, and sizes on and off the 32 columns MatchDescriptors screens at a time and the
  // 1024 rows of one matrix-product block.
  const GridCase cases[] = {
      {1, 1, 1, 0},        {1, 1, 1, 2},      {1, 300, 20, 2},      {300, 1, 20, 2},
      {1, 31, 2, 1},       {31, 1, 2, 1},     {5, 32, 3, 1},        {17, 33, 4, 1},
      {40, 200, 1, 2},     {70, 65, 5, 2},    {1024, 64, 30, 2},    {1025, 100, 40, 2},
      {1100, 1037, 60, 3}, {2049, 47, 20, 2}, {1500, 1001, 300, 6},
  };
  std::mt19937 rng(21);
  ReferenceTies ties;
  for (const GridCase& c : cases) {
    const DescriptorMatrix bases = GridBases(c.bases, rng);
    const DescriptorMatrix a = GridRows(bases, c.n1, c.max_steps, rng);
    const DescriptorMatrix b = GridRows(bases, c.n2, c.max_steps, rng);
    const std::vector<float> distances = SquaredDistances(a, b);
    for (const bool cross_check : {true, false}) {
      for (const double max_ratio : {0.8, 1.0}) {
        SCOPED_TRACE(testing::Message() << c.n1 << " x " << c.n2 << ", cross_check " << cross_check
                                        << ", max_ratio " << max_ratio);
        MatchingOptions options;
        options.cross_check = cross_check;
        options.max_ratio = max_ratio;
        std::vector<std::pair<int, int>> fast;
        for (const FeatureMatch& m : MatchDescriptors(a, b, options)) {
          fast.emplace_back(m.index1, m.index2);
        }
        EXPECT_EQ(fast, ReferenceMatch(distances, c.n1, c.n2, options, &ties));
      }
    }
  }
  // The data exercises both tie rules.
  EXPECT_GT(ties.repeated_minima, 100);
  EXPECT_GT(ties.column_ties, 100);
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

// Two views of random points with exact geometry: F, keypoints, one descriptor per point
// (noisy copies in the second view).
struct TwoViews {
  Eigen::Matrix3d F;
  std::vector<Eigen::Vector2d> keypoints1, keypoints2;
  DescriptorMatrix descriptors1, descriptors2;
};

TwoViews MakeTwoViews(int n, std::mt19937& rng) {
  Eigen::Matrix3d K;
  K << 1000, 0, 640, 0, 1000, 480, 0, 0, 1;
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.15, Eigen::Vector3d(0.1, 1, 0).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(-1.0, 0.1, 0.05);  // Camera 2 = R X + t.
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  TwoViews v;
  v.F = K.inverse().transpose() * tx * R * K.inverse();
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  while (static_cast<int>(v.keypoints1.size()) < n) {
    const Eigen::Vector3d X(2.5 * u(rng), 2.0 * u(rng), 8.0 + 2.0 * u(rng));
    const Eigen::Vector3d x1 = K * X, x2 = K * (R * X + t);
    const Eigen::Vector2d p1 = x1.hnormalized(), p2 = x2.hnormalized();
    if (p1.x() < 0 || p1.x() > 1280 || p1.y() < 0 || p1.y() > 960 || p2.x() < 0 || p2.x() > 1280 ||
        p2.y() < 0 || p2.y() > 960)
      continue;
    v.keypoints1.push_back(p1);
    v.keypoints2.push_back(p2);
  }
  v.descriptors1 = RandomUnitRows(n, rng);
  v.descriptors2 = v.descriptors1;
  std::normal_distribution<float> noise(0.0f, 0.01f);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 128; ++c) v.descriptors2(i, c) += noise(rng);
    v.descriptors2.row(i).normalize();
  }
  return v;
}

double SampsonDistance(const Eigen::Matrix3d& F,
                       const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector3d l2 = F * a.homogeneous(), l1 = F.transpose() * b.homogeneous();
  return std::abs(b.homogeneous().dot(l2)) /
         std::sqrt(l2.head<2>().squaredNorm() + l1.head<2>().squaredNorm());
}

TEST(GuidedMatchingOptions, Check) {
  std::string error;
  EXPECT_TRUE(GuidedMatchingOptions().Check(&error)) << error;
  GuidedMatchingOptions bad;
  bad.max_sampson_px = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("max_sampson_px"), std::string::npos);
}

TEST(GuidedMatchDescriptors, RecoversMatchesThatRepeatedTextureHidFromTheRatioTest) {
  std::mt19937 rng(11);
  TwoViews v = MakeTwoViews(600, rng);
  // Repeated texture: the first 200 points have a twin in view 2 (same descriptor, a little
  // noise) far from their epipolar line, which defeats the unguided ratio test.
  const int n = 600, twins = 200;
  DescriptorMatrix descriptors2(n + twins, 128);
  descriptors2.topRows(n) = v.descriptors2;
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int i = 0; i < twins; ++i) {
    descriptors2.row(n + i) = v.descriptors2.row(i);
    for (int c = 0; c < 128; ++c) descriptors2(n + i, c) += noise(rng);
    descriptors2.row(n + i).normalize();
    // Move away from the line through the true position: along the line's normal.
    const Eigen::Vector3d line = v.F * v.keypoints1[i].homogeneous();
    const Eigen::Vector2d normal = line.head<2>().normalized();
    Eigen::Vector2d twin = v.keypoints2[i] + 150.0 * normal;
    if (twin.x() < 0 || twin.x() > 1280 || twin.y() < 0 || twin.y() > 960) {
      twin = v.keypoints2[i] - 150.0 * normal;
    }
    v.keypoints2.push_back(twin);
  }

  const auto plain = MatchDescriptors(v.descriptors1, descriptors2, MatchingOptions());
  for (const FeatureMatch& m : plain) EXPECT_GE(m.index1, twins) << "the twins confuse it";
  EXPECT_EQ(static_cast<int>(plain.size()), n - twins);

  const auto guided = GuidedMatchDescriptors(v.descriptors1, descriptors2, v.keypoints1,
                                             v.keypoints2, v.F, GuidedMatchingOptions());
  ASSERT_EQ(static_cast<int>(guided.size()), n) << "every point, twins included";
  for (const FeatureMatch& m : guided) {
    EXPECT_EQ(m.index2, m.index1);
    EXPECT_LT(SampsonDistance(v.F, v.keypoints1[m.index1], v.keypoints2[m.index2]), 3.0);
  }
}

TEST(GuidedMatchDescriptors, TwinOnTheEpipolarLineStaysAmbiguousAndStrangersStayUnmatched) {
  std::mt19937 rng(12);
  TwoViews v = MakeTwoViews(300, rng);
  // Point 0 gets a twin on its own epipolar line (30 px along it): guided matching cannot
  // tell them apart either. Points 1..49 of view 1 get unrelated descriptors.
  const Eigen::Vector3d line = v.F * v.keypoints1[0].homogeneous();
  const Eigen::Vector2d along(-line.y(), line.x());
  DescriptorMatrix descriptors2(301, 128);
  descriptors2.topRows(300) = v.descriptors2;
  descriptors2.row(300) = v.descriptors2.row(0);
  v.keypoints2.push_back(v.keypoints2[0] + 30.0 * along.normalized());
  DescriptorMatrix descriptors1 = v.descriptors1;
  descriptors1.middleRows(1, 49) = RandomUnitRows(49, rng);

  const auto guided = GuidedMatchDescriptors(descriptors1, descriptors2, v.keypoints1, v.keypoints2,
                                             v.F, GuidedMatchingOptions());
  EXPECT_EQ(guided.size(), 250u);
  for (const FeatureMatch& m : guided) {
    EXPECT_GE(m.index1, 50);
    EXPECT_EQ(m.index2, m.index1);
  }
}

// The plain rule of GuidedMatchDescriptors' epipolar test, evaluated as the loop over all pairs
// it replaced did (the same expressions, so the same roundings): Sampson distance² under
// max_sampson_px².
bool EpipolarCandidate(const Eigen::Matrix3d& F,
                       const Eigen::Vector2d& x1,
                       const Eigen::Vector2d& x2,
                       double max_sampson_px) {
  const Eigen::Vector3d line2 = F * x1.homogeneous();
  const Eigen::Vector3d point2 = x2.homogeneous();
  const double e = line2.dot(point2);
  const double denominator =
      line2.head<2>().squaredNorm() + (F.transpose() * point2).head<2>().squaredNorm();
  return e * e <= max_sampson_px * max_sampson_px * denominator;
}

// The distances GuidedMatchDescriptors compares, by brute force: 2 - 2 a·b (exact for GridRows
// descriptors) for the epipolar candidates, infinity elsewhere. ReferenceMatch on them applies
// its rules (a non-candidate's infinity never is a nearest or second-nearest distance).
std::vector<float> GuidedDistances(const DescriptorMatrix& a,
                                   const DescriptorMatrix& b,
                                   const std::vector<Eigen::Vector2d>& x1,
                                   const std::vector<Eigen::Vector2d>& x2,
                                   const Eigen::Matrix3d& F,
                                   double max_sampson_px,
                                   int* num_candidates) {
  const int n1 = static_cast<int>(a.rows()), n2 = static_cast<int>(b.rows());
  std::vector<float> d(static_cast<std::size_t>(n1) * n2, std::numeric_limits<float>::infinity());
  for (int i = 0; i < n1; ++i) {
    for (int j = 0; j < n2; ++j) {
      if (!EpipolarCandidate(F, x1[i], x2[j], max_sampson_px)) continue;
      d[static_cast<std::size_t>(i) * n2 + j] =
          std::max(0.0f, 2.0f - 2.0f * a.row(i).dot(b.row(j)));
      ++*num_candidates;
    }
  }
  return d;
}

MatchingOptions AsMatchingOptions(const GuidedMatchingOptions& o) {
  MatchingOptions m;
  m.max_ratio = o.max_ratio;
  m.max_distance = o.max_distance;
  m.cross_check = o.cross_check;
  return m;
}

std::vector<std::pair<int, int>> Guided(const DescriptorMatrix& a,
                                        const DescriptorMatrix& b,
                                        const std::vector<Eigen::Vector2d>& x1,
                                        const std::vector<Eigen::Vector2d>& x2,
                                        const Eigen::Matrix3d& F,
                                        const GuidedMatchingOptions& options) {
  std::vector<std::pair<int, int>> matches;
  for (const FeatureMatch& m : GuidedMatchDescriptors(a, b, x1, x2, F, options)) {
    matches.emplace_back(m.index1, m.index2);
  }
  return matches;
}

// Keypoints of image 2 for the guided matching of `x1`'s points: uniform ones, ones near the
// epipolar line of a random point of x1 (0 to 3 px off, either side of 1.5 px), exact copies
// of earlier ones, and pairs straddling the 1.5 px boundary as closely as doubles allow (the
// last one that passes and the first that fails, by bisection along the line's normal), where a
// different rounding of the test would show.
std::vector<Eigen::Vector2d> GuidedKeypoints2(const Eigen::Matrix3d& F,
                                              const std::vector<Eigen::Vector2d>& x1,
                                              int n2,
                                              std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::uniform_int_distribution<int> pick1(0, static_cast<int>(x1.size()) - 1);
  std::vector<Eigen::Vector2d> x2;
  while (static_cast<int>(x2.size()) < n2) {
    const double kind = u(rng);
    if (kind < 0.3 || x2.empty()) {
      x2.emplace_back(800.0 * u(rng), 600.0 * u(rng));
      continue;
    }
    if (kind < 0.4) {
      x2.push_back(x2[std::uniform_int_distribution<int>(0, static_cast<int>(x2.size()) - 1)(rng)]);
      continue;
    }
    // A point of the line l = F x1 inside the image: the line's foot from a random point.
    const Eigen::Vector2d& p1 = x1[pick1(rng)];
    const Eigen::Vector3d l = F * p1.homogeneous();
    const Eigen::Vector2d normal = l.head<2>().normalized();
    const Eigen::Vector2d random(800.0 * u(rng), 600.0 * u(rng));
    const Eigen::Vector2d foot =
        random - (l.dot(random.homogeneous()) / l.head<2>().norm()) * normal;
    if (kind < 0.85) {
      x2.push_back(foot + (6.0 * u(rng) - 3.0) * normal);
      continue;
    }
    double inside = 0.0, outside = 10.0;  // Offsets along the normal.
    if (!EpipolarCandidate(F, p1, foot, 1.5)) continue;
    for (int step = 0; step < 200; ++step) {
      const double middle = 0.5 * (inside + outside);
      if (middle == inside || middle == outside) break;
      (EpipolarCandidate(F, p1, foot + middle * normal, 1.5) ? inside : outside) = middle;
    }
    x2.push_back(foot + inside * normal);
    x2.push_back(foot + outside * normal);
  }
  x2.resize(n2);
  return x2;
}

TEST(GuidedMatchDescriptors, EqualsBruteForceExactlyNearTheEpipolarBoundWithTies) {
  const GridCase cases[] = {{1, 1, 1, 0},       {1, 40, 3, 1},      {40, 1, 3, 1},
                            {7, 300, 5, 1},     {300, 7, 5, 1},     {333, 517, 8, 1},
                            {1201, 999, 20, 2}, {2500, 2047, 40, 2}};
  // Camera 2 = R X + t: sideways (epipoles far outside the image), forward (inside), oblique.
  struct Motion {
    double angle;
    Eigen::Vector3d axis, t;
  };
  const Motion motions[] = {{0.15, {0.1, 1.0, 0.0}, {-1.0, 0.1, 0.05}},
                            {0.05, {1.0, 0.2, 0.1}, {0.1, -0.05, -1.0}},
                            {0.3, {0.3, -1.0, 0.5}, {-0.6, 0.4, 0.5}}};
  Eigen::Matrix3d K;
  K << 800, 0, 400, 0, 800, 300, 0, 0, 1;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ReferenceTies ties;
  int candidates = 0, matched = 0;
  for (const GridCase& c : cases) {
    for (const Motion& motion : motions) {
      const Eigen::Matrix3d R = Eigen::AngleAxisd(motion.angle, motion.axis.normalized()).matrix();
      Eigen::Matrix3d tx;
      tx << 0, -motion.t.z(), motion.t.y(), motion.t.z(), 0, -motion.t.x(), -motion.t.y(),
          motion.t.x(), 0;
      const Eigen::Matrix3d F = K.inverse().transpose() * tx * R * K.inverse();
      std::vector<Eigen::Vector2d> x1;
      for (int i = 0; i < c.n1; ++i) x1.emplace_back(800.0 * u(rng), 600.0 * u(rng));
      std::vector<Eigen::Vector2d> x2 = GuidedKeypoints2(F, x1, c.n2, rng);
      if (c.n1 > 100 && c.n2 > 100) {  // Non-finite keypoints: NaN (never a candidate), infinity.
        const double inf = std::numeric_limits<double>::infinity();
        x1[3] = {std::nan(""), 10.0};
        x1[5] = {inf, 10.0};
        x2[4] = {10.0, std::nan("")};
        x2[6] = {-inf, 20.0};
      }
      const DescriptorMatrix bases = GridBases(c.bases, rng);
      const DescriptorMatrix a = GridRows(bases, c.n1, c.max_steps, rng);
      const DescriptorMatrix b = GridRows(bases, c.n2, c.max_steps, rng);
      const std::vector<float> distances = GuidedDistances(a, b, x1, x2, F, 1.5, &candidates);
      for (const bool cross_check : {true, false}) {
        for (const double max_ratio : {0.8, 1.0}) {
          SCOPED_TRACE(testing::Message()
                       << c.n1 << " x " << c.n2 << ", t " << motion.t.transpose()
                       << ", cross_check " << cross_check << ", max_ratio " << max_ratio);
          GuidedMatchingOptions options;
          options.cross_check = cross_check;
          options.max_ratio = max_ratio;
          const auto slow =
              ReferenceMatch(distances, c.n1, c.n2, AsMatchingOptions(options), &ties);
          EXPECT_EQ(Guided(a, b, x1, x2, F, options), slow);
          matched += static_cast<int>(slow.size());
        }
      }
    }
  }
  // The data exercises the rules: many candidates and matches, both tie rules.
  EXPECT_GT(candidates, 100000);
  EXPECT_GT(matched, 1000);
  EXPECT_GT(ties.repeated_minima, 100);
  EXPECT_GT(ties.column_ties, 100);
}

// F = [0 0 0; 0 0 -3; 0 4 0]: e = 4 y1 - 3 y2, |line2_xy|² = 9, |(Fᵀ x2)_xy|² = 16, all exact for
// coordinates on a grid of 1/2, so that many pairs have a Sampson distance of exactly 1.5 px
// (|e| = 7.5): candidates (<=), and the test's comparison is checked at equality.
TEST(GuidedMatchDescriptors, SampsonDistanceExactlyAtTheBoundIsACandidate) {
  Eigen::Matrix3d F;
  F << 0, 0, 0, 0, 0, -3, 0, 4, 0;
  std::mt19937 rng(29);
  std::uniform_int_distribution<int> half_pixels(0, 120);
  std::vector<Eigen::Vector2d> x1, x2;
  for (int i = 0; i < 301; ++i) x1.emplace_back(0.5 * half_pixels(rng), 0.5 * half_pixels(rng));
  for (int j = 0; j < 397; ++j) x2.emplace_back(0.5 * half_pixels(rng), 0.5 * half_pixels(rng));
  int on_bound = 0;
  for (const Eigen::Vector2d& p : x1) {
    for (const Eigen::Vector2d& q : x2) on_bound += std::abs(4 * p.y() - 3 * q.y()) == 7.5;
  }
  ASSERT_GT(on_bound, 300);
  const DescriptorMatrix bases = GridBases(30, rng);
  const DescriptorMatrix a = GridRows(bases, 301, 1, rng), b = GridRows(bases, 397, 1, rng);
  int candidates = 0;
  const std::vector<float> distances = GuidedDistances(a, b, x1, x2, F, 1.5, &candidates);
  ReferenceTies ties;
  for (const bool cross_check : {true, false}) {
    SCOPED_TRACE(testing::Message() << "cross_check " << cross_check);
    GuidedMatchingOptions options;
    options.cross_check = cross_check;
    EXPECT_EQ(Guided(a, b, x1, x2, F, options),
              ReferenceMatch(distances, 301, 397, AsMatchingOptions(options), &ties));
  }
}

TEST(GuidedMatchDescriptors, EmptyInputGivesNoMatches) {
  const DescriptorMatrix none(0, 128);
  EXPECT_TRUE(GuidedMatchDescriptors(none, none, {}, {}, Eigen::Matrix3d::Identity(), {}).empty());
}

}  // namespace
}  // namespace reconduit
