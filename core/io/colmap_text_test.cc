#include "core/io/colmap_text.h"

#include "core/io/file_util.h"
#include "core/io/sparse_model_test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using testing_util::DistortedSceneOptions;
using testing_util::FreshTestFolder;
using testing_util::SyntheticReconstruction;

// Data lines (not comments) of a file, split at spaces. For images.txt the POINTS2D line of
// an image with no keypoints is empty and kept.
std::vector<std::vector<std::string>> DataLines(const fs::path& path) {
  Result<std::string> text = ReadFile(path);
  THROW_CHECK(text.ok()) << text.status();
  std::vector<std::vector<std::string>> lines;
  std::istringstream in(*text);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '#') continue;
    std::vector<std::string> tokens;
    std::istringstream fields(line);
    for (std::string token; fields >> token;) tokens.push_back(token);
    lines.push_back(tokens);
  }
  return lines;
}

class ColmapTextTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rec_ = SyntheticReconstruction(DistortedSceneOptions());
    dir_ = FreshTestFolder();
  }
  void TearDown() override { fs::remove_all(dir_); }

  Reconstruction rec_;
  fs::path dir_;
};

TEST_F(ColmapTextTest, RoundTripReproducesPosesIntrinsicsAndObservations) {
  ASSERT_TRUE(WriteColmapText(dir_ / "sparse", rec_).ok());
  Result<Reconstruction> read = ReadColmapText(dir_ / "sparse");
  ASSERT_TRUE(read.ok()) << read.status();

  ASSERT_EQ(read->cameras.size(), rec_.cameras.size());
  for (const auto& [id, camera] : rec_.cameras) {
    ASSERT_TRUE(read->cameras.contains(id)) << "camera ids map back (COLMAP id - 1)";
    const Camera& c = read->cameras.at(id);
    EXPECT_EQ(c.width, camera.width);
    EXPECT_EQ(c.height, camera.height);
    EXPECT_EQ(c.focal, camera.focal);
    EXPECT_NEAR(c.cx, camera.cx, 1e-12);
    EXPECT_NEAR(c.cy, camera.cy, 1e-12);
    EXPECT_EQ(c.k1, camera.k1);
    EXPECT_EQ(c.k2, camera.k2);
  }
  ASSERT_EQ(read->images.size(), rec_.images.size());
  for (const auto& [id, image] : rec_.images) {
    ASSERT_TRUE(read->images.contains(id));
    const RegisteredImage& r = read->images.at(id);
    EXPECT_EQ(r.image_id, id);
    EXPECT_EQ(r.camera_id, image.camera_id);
    EXPECT_EQ(r.name, image.name);
    EXPECT_LT((r.cam_from_world.rotation.toRotationMatrix() -
               image.cam_from_world.rotation.toRotationMatrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12);
    EXPECT_LT((r.cam_from_world.translation - image.cam_from_world.translation).norm(), 1e-12);
    ASSERT_EQ(r.keypoints.size(), image.keypoints.size());
    for (std::size_t k = 0; k < r.keypoints.size(); ++k) {
      EXPECT_LT((r.keypoints[k] - image.keypoints[k]).norm(), 1e-12) << "keypoint " << k;
    }
    EXPECT_EQ(r.point_for_keypoint, image.point_for_keypoint);
  }
  ASSERT_EQ(read->points.size(), rec_.points.size());
  for (const auto& [id, point] : rec_.points) {
    ASSERT_TRUE(read->points.contains(id)) << "point " << id;
    const Point3D& p = read->points.at(id);
    EXPECT_EQ(p.xyz_in_world, point.xyz_in_world);
    EXPECT_EQ(p.rgb, point.rgb);
    EXPECT_EQ(p.error, point.error);
    ASSERT_EQ(p.observations.size(), point.observations.size());
    for (std::size_t k = 0; k < p.observations.size(); ++k) {
      EXPECT_EQ(p.observations[k].image_id, point.observations[k].image_id);
      EXPECT_EQ(p.observations[k].keypoint, point.observations[k].keypoint);
    }
  }
  EXPECT_EQ(read->NumObservations(), rec_.NumObservations());
}

TEST_F(ColmapTextTest, FilesHaveTheSpecColumnsIdsAndHalfPixelShift) {
  ASSERT_TRUE(WriteColmapText(dir_, rec_).ok());

  // cameras.txt: CAMERA_ID RADIAL WIDTH HEIGHT f cx cy k1 k2.
  const auto cameras = DataLines(dir_ / "cameras.txt");
  ASSERT_EQ(cameras.size(), rec_.cameras.size());
  for (const auto& line : cameras) EXPECT_EQ(line.size(), 9u);
  {
    const auto& [id, camera] = *rec_.cameras.begin();
    const auto& line = cameras.front();
    EXPECT_EQ(std::stoi(line[0]), id + 1);
    EXPECT_EQ(line[1], "RADIAL");
    EXPECT_EQ(std::stoi(line[2]), camera.width);
    EXPECT_EQ(std::stoi(line[3]), camera.height);
    EXPECT_EQ(std::stod(line[4]), camera.focal);
    EXPECT_EQ(std::stod(line[5]), camera.cx + 0.5) << "COLMAP's pixel centres are at +0.5";
    EXPECT_EQ(std::stod(line[6]), camera.cy + 0.5);
    EXPECT_EQ(std::stod(line[7]), camera.k1);
    EXPECT_EQ(std::stod(line[8]), camera.k2);
  }

  // images.txt: two lines per image; IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, then
  // (X, Y, POINT3D_ID) triplets.
  const auto images = DataLines(dir_ / "images.txt");
  ASSERT_EQ(images.size(), 2 * rec_.images.size());
  {
    const RegisteredImage& image = rec_.images.at(0);
    const auto& header = images[0];
    ASSERT_EQ(header.size(), 10u) << "name without spaces: exactly 10 columns";
    EXPECT_EQ(std::stoi(header[0]), 1);
    EXPECT_EQ(std::stod(header[1]), image.cam_from_world.rotation.w());
    EXPECT_EQ(std::stod(header[2]), image.cam_from_world.rotation.x());
    EXPECT_EQ(std::stod(header[3]), image.cam_from_world.rotation.y());
    EXPECT_EQ(std::stod(header[4]), image.cam_from_world.rotation.z());
    EXPECT_EQ(std::stod(header[5]), image.cam_from_world.translation.x());
    EXPECT_EQ(std::stod(header[6]), image.cam_from_world.translation.y());
    EXPECT_EQ(std::stod(header[7]), image.cam_from_world.translation.z());
    EXPECT_EQ(std::stoi(header[8]), image.camera_id + 1);
    EXPECT_EQ(header[9], image.name);
    const auto& points2d = images[1];
    ASSERT_EQ(points2d.size(), 3 * image.keypoints.size());
    int with_point = 0, without_point = 0;
    for (std::size_t k = 0; k < image.keypoints.size(); ++k) {
      EXPECT_EQ(std::stod(points2d[3 * k]), image.keypoints[k].x() + 0.5);
      EXPECT_EQ(std::stod(points2d[3 * k + 1]), image.keypoints[k].y() + 0.5);
      const int point_id = image.point_for_keypoint[k];
      EXPECT_EQ(std::stoi(points2d[3 * k + 2]), point_id == kInvalidId ? -1 : point_id + 1);
      ++(point_id == kInvalidId ? without_point : with_point);
    }
    EXPECT_GT(with_point, 0);
    EXPECT_GT(without_point, 0) << "the test scene has keypoints without points";
  }
  // Image 1's name has spaces: the columns after CAMERA_ID are its words.
  EXPECT_EQ(images[2].size(), 12u);

  // points3D.txt: POINT3D_ID X Y Z R G B ERROR, then (IMAGE_ID, POINT2D_IDX) pairs.
  const auto points = DataLines(dir_ / "points3D.txt");
  ASSERT_EQ(points.size(), rec_.points.size());
  auto point_it = rec_.points.begin();
  for (const auto& line : points) {
    EXPECT_EQ(line.size(), 8 + 2 * point_it->second.observations.size());
    ++point_it;
  }
  {
    const auto& [id, point] = *rec_.points.begin();
    const auto& line = points.front();
    EXPECT_EQ(std::stoi(line[0]), id + 1);
    EXPECT_EQ(std::stod(line[1]), point.xyz_in_world.x());
    EXPECT_EQ(std::stod(line[2]), point.xyz_in_world.y());
    EXPECT_EQ(std::stod(line[3]), point.xyz_in_world.z());
    EXPECT_EQ(std::stoi(line[4]), point.rgb[0]);
    EXPECT_EQ(std::stoi(line[5]), point.rgb[1]);
    EXPECT_EQ(std::stoi(line[6]), point.rgb[2]);
    EXPECT_EQ(std::stod(line[7]), point.error);
    for (std::size_t k = 0; k < point.observations.size(); ++k) {
      EXPECT_EQ(std::stoi(line[8 + 2 * k]), point.observations[k].image_id + 1);
      EXPECT_EQ(std::stoi(line[9 + 2 * k]), point.observations[k].keypoint);
    }
  }
}

// A model in the shape COLMAP's model_converter writes: SIMPLE_RADIAL and SIMPLE_PINHOLE
// cameras, sparse ids, an image without keypoints (empty POINTS2D line).
TEST_F(ColmapTextTest, ReadsColmapWrittenModels) {
  ASSERT_TRUE(WriteFileAtomically(dir_ / "cameras.txt",
                                  "# Camera list with one line of data per camera:\n"
                                  "3 SIMPLE_RADIAL 3072 2304 2559.69 1536 1152 -0.0218531\n"
                                  "7 SIMPLE_PINHOLE 640 480 500 320.5 240\n")
                  .ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ / "images.txt",
                                  "# Image list with two lines of data per image:\n"
                                  "5 1 0 0 0 0.5 -1 2 3 P1180141.JPG\n"
                                  "10.5 20.5 42 30 40 -1\n"
                                  "9 0.7071067811865476 0 0.7071067811865476 0 0 0 0 7 b.jpg\n"
                                  "100 200.5 42\n"
                                  "12 1 0 0 0 0 0 0 7 empty.jpg\n"
                                  "\n")
                  .ok());
  ASSERT_TRUE(WriteFileAtomically(dir_ / "points3D.txt",
                                  "# 3D point list with one line of data per point:\n"
                                  "42 1.5 -2 3 255 0 10 0.75 5 0 9 0\n")
                  .ok());
  Result<Reconstruction> read = ReadColmapText(dir_);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->cameras.size(), 2u);
  const Camera& radial = read->cameras.at(2);
  EXPECT_EQ(radial.focal, 2559.69);
  EXPECT_EQ(radial.cx, 1535.5);
  EXPECT_EQ(radial.cy, 1151.5);
  EXPECT_EQ(radial.k1, -0.0218531);
  EXPECT_EQ(radial.k2, 0.0);
  EXPECT_EQ(read->cameras.at(6).cx, 320.0);
  ASSERT_EQ(read->images.size(), 3u);
  const RegisteredImage& first = read->images.at(4);
  EXPECT_EQ(first.camera_id, 2);
  EXPECT_EQ(first.name, "P1180141.JPG");
  EXPECT_EQ(first.cam_from_world.translation, Eigen::Vector3d(0.5, -1, 2));
  ASSERT_EQ(first.keypoints.size(), 2u);
  EXPECT_EQ(first.keypoints[0], Eigen::Vector2d(10, 20));
  EXPECT_EQ(first.point_for_keypoint, (std::vector<int>{41, kInvalidId}));
  EXPECT_TRUE(read->images.at(11).keypoints.empty());
  ASSERT_EQ(read->points.size(), 1u);
  const Point3D& point = read->points.at(41);
  EXPECT_EQ(point.xyz_in_world, Eigen::Vector3d(1.5, -2, 3));
  EXPECT_EQ(point.rgb, (Eigen::Matrix<std::uint8_t, 3, 1>(255, 0, 10)));
  EXPECT_EQ(point.error, 0.75);
  ASSERT_EQ(point.observations.size(), 2u);
  EXPECT_EQ(point.observations[1].image_id, 8);
  EXPECT_EQ(point.observations[1].keypoint, 0);
}

TEST_F(ColmapTextTest, BadFilesGiveClearErrors) {
  ASSERT_TRUE(WriteColmapText(dir_, rec_).ok());
  const std::string cameras = *ReadFile(dir_ / "cameras.txt");
  const std::string images = *ReadFile(dir_ / "images.txt");
  const std::string points = *ReadFile(dir_ / "points3D.txt");
  const auto expect_error = [&](const std::string& file, const std::string& contents,
                                const std::string& fragment) {
    ASSERT_TRUE(WriteFileAtomically(dir_ / file, contents).ok());
    const Status status = ReadColmapText(dir_).status();
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status;
    EXPECT_NE(status.message().find(fragment), std::string::npos)
        << "expected '" << fragment << "' in: " << status.message();
    ASSERT_TRUE(WriteFileAtomically(dir_ / "cameras.txt", cameras).ok());
    ASSERT_TRUE(WriteFileAtomically(dir_ / "images.txt", images).ok());
    ASSERT_TRUE(WriteFileAtomically(dir_ / "points3D.txt", points).ok());
  };
  expect_error("cameras.txt", "1 RADIAL 640 480 500 320 240 0.1\n",
               "cameras.txt:1: RADIAL needs 9 columns, found 8");
  expect_error("cameras.txt", "1 OPENCV 640 480 500 500 320 240 0 0 0 0\n",
               "unsupported camera model OPENCV");
  expect_error("cameras.txt", "1 PINHOLE 640 480 500 501 320 240\n", "fx != fy");
  expect_error("images.txt", "1 1 0 0 0 0 0 0 1\n\n", "images.txt:1: expected IMAGE_ID");
  expect_error("images.txt", "1 1 0 0 0 0 0 0 1 a.jpg\n1 2\n", "images.txt:2: POINTS2D");
  expect_error("images.txt", "1 1 0 0 0 0 0 0 99 a.jpg\n\n", "unknown CAMERA_ID 99");
  expect_error("points3D.txt", "1 0 0 0 1 2 3 0.5 1\n", "points3D.txt:1: expected");
  expect_error("points3D.txt", "1 0 0 0 1 2 300 0.5 1 0 2 0\n", "colour");
  // A track that disagrees with POINT3D_ID in images.txt: drop the first point's line.
  std::string fewer_points = points;
  const std::size_t first_data = fewer_points.find("\n", fewer_points.rfind("# ")) + 1;
  fewer_points.erase(first_data, fewer_points.find('\n', first_data) + 1 - first_data);
  expect_error("points3D.txt", fewer_points, "but points3D.txt says -1");

  fs::remove(dir_ / "points3D.txt");
  EXPECT_EQ(ReadColmapText(dir_).status().code(), StatusCode::kNotFound);
}

TEST_F(ColmapTextTest, WriterRefusesNamesWithLineBreaks) {
  rec_.images.at(0).name = "two\nlines.jpg";
  const Status status = WriteColmapText(dir_, rec_);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status;
}

}  // namespace
}  // namespace reconduit
