#include "core/eval/camera_evaluation.h"

#include "core/eval/ground_truth.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// A reconstruction that is the ground truth moved by a similarity (scale 0.3, a rotation and
// a shift) must evaluate to zero error; a perturbed one to the perturbation.
TEST(EvaluateCameras, InvariantToSimilarityAndSensitiveToErrors) {
  std::vector<GroundTruthCamera> truth;
  Reconstruction rec;
  rec.cameras[0] = Camera::FromFocal(1000, 800, 1200.0);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const Eigen::Vector3d shift(5, -2, 1);
  const double s = 0.3;
  for (int i = 0; i < 6; ++i) {
    GroundTruthCamera gt;
    gt.name = "img" + std::to_string(i) + ".jpg";
    gt.K << 1200, 0, 500, 0, 1200, 400, 0, 0, 1;
    const double a = i * 0.4;
    gt.cam_from_world = Rigid3d::LookAt({4 * std::sin(a), 0.3 * i, -4 * std::cos(a)}, {0, 0, 0});
    truth.push_back(gt);
    // World' = s q World + shift  =>  cam_from_world' = [R qᵀ | s t - R qᵀ shift] / scale handled
    // through the centre: C' = s q C + shift, R' = R qᵀ.
    const Eigen::Matrix3d r =
        gt.cam_from_world.rotation.toRotationMatrix() * q.toRotationMatrix().transpose();
    const Eigen::Vector3d c = s * (q * gt.cam_from_world.CenterInWorld()) + shift;
    RegisteredImage image;
    image.image_id = i;
    image.camera_id = 0;
    image.name = gt.name;
    image.cam_from_world = Rigid3d(r, -r * c);
    rec.images[i] = image;
  }
  CameraEvaluation e = EvaluateCameras(rec, truth);
  EXPECT_EQ(e.num_registered, 6);
  EXPECT_LT(e.mean_center_error, 1e-9);
  EXPECT_LT(e.mean_rotation_error_deg, 1e-6);
  EXPECT_LT(e.mean_relative_rotation_error_deg, 1e-6);
  EXPECT_NEAR(e.mean_focal_error_percent, 0.0, 1e-12);

  rec.cameras[0].focal = 1212.0;  // +1 %
  RegisteredImage& moved = rec.images[2];
  const Eigen::Vector3d c = moved.cam_from_world.CenterInWorld() + Eigen::Vector3d(0.03, 0, 0);
  moved.cam_from_world.translation = -(moved.cam_from_world.rotation * c);
  e = EvaluateCameras(rec, truth);
  EXPECT_NEAR(e.mean_focal_error_percent, 1.0, 1e-9);
  EXPECT_FALSE(e.ground_truth_non_square);
  EXPECT_EQ(e.Report().find("vs fy"), std::string::npos);
  EXPECT_GT(e.max_center_error, 0.03);  // 0.03 reconstruction units = 0.1 true units...
  EXPECT_LT(e.max_center_error, 0.12);  // ...shared out by the least-squares alignment.
}

// Ground truth with fx != fy: the focal is compared with their mean and with each.
TEST(EvaluateCameras, NonSquareGroundTruthReportsBothAxes) {
  std::vector<GroundTruthCamera> truth;
  Reconstruction rec;
  rec.cameras[0] = Camera::FromFocal(1000, 800, 1000.0);
  for (int i = 0; i < 4; ++i) {
    GroundTruthCamera gt;
    gt.name = "p" + std::to_string(i);
    gt.K << 990, 0, 500, 0, 1010, 400, 0, 0, 1;
    gt.cam_from_world = Rigid3d::LookAt({4 * std::sin(0.5 * i), 0.2 * i, -4}, {0, 0, 0});
    truth.push_back(gt);
    RegisteredImage image;
    image.image_id = i;
    image.camera_id = 0;
    image.name = gt.name;
    image.cam_from_world = gt.cam_from_world;
    rec.images[i] = image;
  }
  const CameraEvaluation e = EvaluateCameras(rec, truth);
  EXPECT_NEAR(e.mean_focal_error_percent, 0.0, 1e-12);
  EXPECT_NEAR(e.mean_focal_error_x_percent, 100.0 * 10.0 / 990.0, 1e-9);
  EXPECT_NEAR(e.mean_focal_error_y_percent, 100.0 * 10.0 / 1010.0, 1e-9);
  EXPECT_TRUE(e.ground_truth_non_square);
  EXPECT_NE(e.Report().find("focal error vs fx, vs fy  1.010 %, 0.990 %"), std::string::npos)
      << e.Report();
}

TEST(EvaluateCameras, CountsMissingPhotos) {
  std::vector<GroundTruthCamera> truth(4);
  for (int i = 0; i < 4; ++i) truth[i].name = "p" + std::to_string(i);
  Reconstruction rec;
  const CameraEvaluation e = EvaluateCameras(rec, truth);
  EXPECT_EQ(e.num_registered, 0);
  EXPECT_EQ(e.missing.size(), 4u);
}

TEST(ReadGroundTruth, StrechaAndMiddleburyAgreeOnConventions) {
  const fs::path dir =
      fs::temp_directory_path() / ("reconduit_gt_test_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "strecha");
  // One camera at C = (1, 2, 3), camera-to-world rotation = identity, in both formats.
  std::ofstream(dir / "strecha" / "a.jpg.camera")
      << "1000 0 500\n0 1000 400\n0 0 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 2 3\n1000 800\n";
  std::ofstream(dir / "x_par.txt")
      << "1\na.jpg 1000 0 500 0 1000 400 0 0 1 1 0 0 0 1 0 0 0 1 -1 -2 -3";
  auto strecha = ReadGroundTruth(dir / "strecha");
  auto middlebury = ReadGroundTruth(dir / "x_par.txt");
  ASSERT_TRUE(strecha.ok()) << strecha.status();
  ASSERT_TRUE(middlebury.ok()) << middlebury.status();
  EXPECT_EQ((*strecha)[0].name, "a.jpg");
  EXPECT_EQ((*strecha)[0].width, 1000);
  EXPECT_LT(((*strecha)[0].cam_from_world.CenterInWorld() - Eigen::Vector3d(1, 2, 3)).norm(),
            1e-12);
  EXPECT_LT(((*middlebury)[0].cam_from_world.CenterInWorld() - Eigen::Vector3d(1, 2, 3)).norm(),
            1e-12);
  std::ofstream(dir / "bad_par.txt") << "2\na.jpg 1 2 3";
  EXPECT_FALSE(ReadGroundTruth(dir / "bad_par.txt").ok());
  EXPECT_FALSE(ReadGroundTruth(dir / "missing").ok());
  fs::remove_all(dir);
}

TEST(FormatMiddleburyPar, ReadsBackTheSameCameras) {
  std::vector<GroundTruthCamera> cameras(2);
  cameras[0].name = "0000.jpg";
  cameras[0].K << 700, 0, 399.5, 0, 700, 299.5, 0, 0, 1;
  cameras[0].cam_from_world =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
              Eigen::Vector3d(0.1, -2.5, 10.25));
  cameras[1].name = "0001.jpg";
  cameras[1].K << 1234.5, 0, 10, 0, 1234.5, 20, 0, 0, 1;
  const fs::path file =
      fs::temp_directory_path() / ("reconduit_par_test_" + std::to_string(getpid()) + "_par.txt");
  std::ofstream(file) << FormatMiddleburyPar(cameras);
  auto read = ReadMiddleburyPar(file);
  fs::remove(file);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ((*read)[i].name, cameras[i].name);
    EXPECT_LT(((*read)[i].K - cameras[i].K).norm(), 1e-9);
    EXPECT_LT(
        ((*read)[i].cam_from_world.translation - cameras[i].cam_from_world.translation).norm(),
        1e-12);
    EXPECT_LT(
        (*read)[i].cam_from_world.rotation.angularDistance(cameras[i].cam_from_world.rotation),
        1e-12);
  }
}

TEST(ReadGroundTruth, DatasetsWhenPresent) {
  const fs::path fountain = "../shared/datasets/fountain-P11/gt";
  const fs::path temple = "../shared/datasets/templeSparseRing/gt/templeSR_par.txt";
  if (!fs::exists(fountain) || !fs::exists(temple)) GTEST_SKIP() << "../shared/datasets absent";
  auto f = ReadGroundTruth(fountain);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(f->size(), 11u);
  EXPECT_EQ((*f)[0].name, "0000.jpg");
  EXPECT_NEAR((*f)[0].K(0, 0), 2759.48, 1e-9);
  auto t = ReadGroundTruth(temple);
  ASSERT_TRUE(t.ok()) << t.status();
  EXPECT_EQ(t->size(), 16u);
  EXPECT_EQ((*t)[0].name, "templeSR0001.png");
}

}  // namespace
}  // namespace reconduit
