#include "core/mvs/depth_map_io.h"

#include "core/io/file_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <random>
#include <unistd.h>

namespace reconduit {
namespace {

class DepthMapIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("reconduit-depth-io-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // 40 x 30, depths in [2, 12] m with a hole, random normals and costs.
  static DepthMap RandomMap() {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    DepthMap map;
    map.depth.create(30, 40, CV_32FC1);
    map.normal.create(30, 40, CV_32FC3);
    map.cost.create(30, 40, CV_32FC1);
    for (int y = 0; y < 30; ++y) {
      for (int x = 0; x < 40; ++x) {
        map.depth.at<float>(y, x) = (x < 5 && y < 5) ? 0.0f : 2.0f + 10.0f * u(rng);
        map.normal.at<cv::Vec3f>(y, x) = {u(rng), u(rng), -u(rng)};
        map.cost.at<float>(y, x) = u(rng);
      }
    }
    return map;
  }

  std::filesystem::path dir_;
};

TEST_F(DepthMapIoTest, BinaryRoundTripIsExact) {
  const DepthMap map = RandomMap();
  ASSERT_TRUE(WriteDepthMapBinary(dir_ / "0.bin", map).ok());
  const Result<DepthMap> back = ReadDepthMapBinary(dir_ / "0.bin");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(cv::norm(back->depth, map.depth, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back->normal, map.normal, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back->cost, map.cost, cv::NORM_INF), 0.0);
}

TEST_F(DepthMapIoTest, BinaryRefusesTruncatedAndForeignFiles) {
  ASSERT_TRUE(WriteDepthMapBinary(dir_ / "0.bin", RandomMap()).ok());
  std::string bytes = *ReadFile(dir_ / "0.bin");
  ASSERT_TRUE(WriteFileAtomically(dir_ / "cut.bin", bytes.substr(0, bytes.size() - 1)).ok());
  EXPECT_EQ(ReadDepthMapBinary(dir_ / "cut.bin").status().code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(WriteFileAtomically(dir_ / "other.bin", "hello").ok());
  EXPECT_EQ(ReadDepthMapBinary(dir_ / "other.bin").status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadDepthMapBinary(dir_ / "missing.bin").status().code(), StatusCode::kNotFound);
}

TEST_F(DepthMapIoTest, PngKeepsDepthToItsStepAndDescribesItself) {
  const DepthMap map = RandomMap();
  const Camera camera = Camera::FromFocal(40, 30, 35.0);
  const Rigid3d pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
                     Eigen::Vector3d(1, 2, 3));
  ASSERT_TRUE(WriteDepthPng(dir_ / "a.png", dir_ / "a.json", map.depth, camera, pose).ok());
  const Result<cv::Mat> back = ReadDepthPng(dir_ / "a.png", dir_ / "a.json");
  ASSERT_TRUE(back.ok()) << back.status().message();
  double lo = 0.0, hi = 0.0;
  cv::minMaxLoc(map.depth, nullptr, &hi);
  lo = hi;
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x)
      if (map.depth.at<float>(y, x) > 0.0f) lo = std::min<double>(lo, map.depth.at<float>(y, x));
  const double step = (hi - lo) / 65534.0;
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) {
      const float d = map.depth.at<float>(y, x);
      if (d == 0.0f) {
        EXPECT_EQ(back->at<float>(y, x), 0.0f);
      } else {
        EXPECT_NEAR(back->at<float>(y, x), d, 0.51 * step + 1e-6);
      }
    }
  }
  const nlohmann::json json = nlohmann::json::parse(*ReadFile(dir_ / "a.json"));
  EXPECT_DOUBLE_EQ(json["depth_min"].get<double>(), lo);
  EXPECT_DOUBLE_EQ(json["camera"]["focal"].get<double>(), 35.0);
  EXPECT_DOUBLE_EQ(json["cam_from_world"]["translation"][2].get<double>(), 3.0);
  // The wrong size is refused.
  EXPECT_EQ(WriteDepthPng(dir_ / "b.png", dir_ / "b.json", map.depth,
                          Camera::FromFocal(41, 30, 35.0), pose)
                .code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reconduit
