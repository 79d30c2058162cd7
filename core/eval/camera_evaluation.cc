#include "core/eval/camera_evaluation.h"

#include <Eigen/Geometry>

#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>

namespace reconduit {
namespace {

double AngleDeg(const Eigen::Matrix3d& r) { return Eigen::AngleAxisd(r).angle() * 180.0 / M_PI; }

}  // namespace

CameraEvaluation EvaluateCameras(const Reconstruction& reconstruction,
                                 const std::vector<GroundTruthCamera>& ground_truth) {
  CameraEvaluation e;
  e.num_ground_truth = static_cast<int>(ground_truth.size());
  std::map<std::string, const RegisteredImage*> by_name;
  for (const auto& [id, image] : reconstruction.images) by_name[image.name] = &image;
  std::vector<const GroundTruthCamera*> gts;
  std::vector<const RegisteredImage*> ests;
  for (const GroundTruthCamera& gt : ground_truth) {
    auto it = by_name.find(gt.name);
    if (it == by_name.end()) {
      e.missing.push_back(gt.name);
      continue;
    }
    gts.push_back(&gt);
    ests.push_back(it->second);
  }
  const int n = static_cast<int>(gts.size());
  e.num_registered = n;
  if (n < 3) return e;

  Eigen::Matrix3Xd estimated(3, n), expected(3, n);
  for (int i = 0; i < n; ++i) {
    estimated.col(i) = ests[i]->cam_from_world.CenterInWorld();
    expected.col(i) = gts[i]->cam_from_world.CenterInWorld();
  }
  const Eigen::Matrix4d sim = Eigen::umeyama(estimated, expected, true);
  const double scale = sim.topLeftCorner<3, 3>().col(0).norm();
  const Eigen::Matrix3d world_rotation = sim.topLeftCorner<3, 3>() / scale;
  const Eigen::Vector3d centroid = expected.rowwise().mean();
  double radius = 0.0;
  for (int i = 0; i < n; ++i) radius += (expected.col(i) - centroid).norm() / n;

  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d aligned = (sim * estimated.col(i).homogeneous()).head<3>();
    const double error = (aligned - expected.col(i)).norm();
    e.mean_center_error += error / n;
    e.max_center_error = std::max(e.max_center_error, error);
    const Eigen::Matrix3d r_est =
        ests[i]->cam_from_world.rotation.toRotationMatrix() * world_rotation.transpose();
    e.mean_rotation_error_deg +=
        AngleDeg(r_est * gts[i]->cam_from_world.rotation.toRotationMatrix().transpose()) / n;
    const Camera& camera = reconstruction.cameras.at(ests[i]->camera_id);
    const double f_true = 0.5 * (gts[i]->K(0, 0) + gts[i]->K(1, 1));
    const double focal_error = 100.0 * std::abs(camera.focal - f_true) / f_true;
    e.mean_focal_error_percent += focal_error / n;
    e.max_focal_error_percent = std::max(e.max_focal_error_percent, focal_error);
    const double fx = gts[i]->K(0, 0), fy = gts[i]->K(1, 1);
    e.mean_focal_error_x_percent += 100.0 * std::abs(camera.focal - fx) / fx / n;
    e.mean_focal_error_y_percent += 100.0 * std::abs(camera.focal - fy) / fy / n;
    e.ground_truth_non_square = e.ground_truth_non_square || fx != fy;
  }
  e.mean_center_error_percent_of_radius = radius > 0 ? 100.0 * e.mean_center_error / radius : 0.0;

  int pairs = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const Eigen::Matrix3d rel_est =
          ests[j]->cam_from_world.rotation.toRotationMatrix() *
          ests[i]->cam_from_world.rotation.toRotationMatrix().transpose();
      const Eigen::Matrix3d rel_gt = gts[j]->cam_from_world.rotation.toRotationMatrix() *
                                     gts[i]->cam_from_world.rotation.toRotationMatrix().transpose();
      const double error = AngleDeg(rel_est * rel_gt.transpose());
      e.mean_relative_rotation_error_deg += error;
      e.max_relative_rotation_error_deg = std::max(e.max_relative_rotation_error_deg, error);
      ++pairs;
    }
  }
  e.mean_relative_rotation_error_deg /= pairs;
  return e;
}

std::string CameraEvaluation::Report() const {
  std::ostringstream s;
  s << std::fixed;
  s << "registered                " << num_registered << "/" << num_ground_truth << "\n";
  if (num_registered >= 3) {
    s << std::setprecision(2);
    s << "centre error, mean        " << 1000.0 * mean_center_error << " mm ("
      << std::setprecision(3) << mean_center_error_percent_of_radius << " % of the scene radius)\n";
    s << std::setprecision(2) << "centre error, max         " << 1000.0 * max_center_error
      << " mm\n";
    s << std::setprecision(3);
    s << "rotation error, mean      " << mean_rotation_error_deg << " deg\n";
    s << "relative rotation, mean   " << mean_relative_rotation_error_deg << " deg (max "
      << max_relative_rotation_error_deg << ")\n";
    s << "focal error, mean         " << mean_focal_error_percent << " % (max "
      << max_focal_error_percent << ")\n";
    if (ground_truth_non_square) {
      s << "focal error vs fx, vs fy  " << mean_focal_error_x_percent << " %, "
        << mean_focal_error_y_percent << " % (the ground truth's pixels are not square)\n";
    }
  }
  for (const std::string& name : missing) s << "not registered            " << name << "\n";
  return s.str();
}

}  // namespace reconduit
