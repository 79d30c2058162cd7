#include "core/eval/ground_truth.h"

#include <algorithm>
#include <fstream>
#include <sstream>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// Orthonormalises a nearly-orthonormal matrix read from text (files carry ~6 digits).
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) r = -r;
  return r;
}

}  // namespace

Result<std::vector<GroundTruthCamera>> ReadStrechaCameras(const fs::path& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return Status::NotFound(folder.string() + " is not a folder");
  std::vector<GroundTruthCamera> cameras;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string file = entry.path().filename().string();
    const std::string suffix = ".camera";
    if (file.size() <= suffix.size() ||
        file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0) {
      continue;
    }
    std::ifstream in(entry.path());
    std::vector<double> v;
    double x;
    while (in >> x) v.push_back(x);
    if (v.size() < 26) {
      return Status::InvalidArgument(entry.path().string() + ": expected 26 numbers, got " +
                                     std::to_string(v.size()));
    }
    GroundTruthCamera camera;
    camera.name = file.substr(0, file.size() - suffix.size());
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) camera.K(r, c) = v[3 * r + c];
    }
    Eigen::Matrix3d world_from_cam;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) world_from_cam(r, c) = v[12 + 3 * r + c];
    }
    const Eigen::Vector3d center(v[21], v[22], v[23]);
    const Eigen::Matrix3d r = NearestRotation(world_from_cam).transpose();
    camera.cam_from_world = Rigid3d(r, -r * center);
    camera.width = static_cast<int>(v[24]);
    camera.height = static_cast<int>(v[25]);
    cameras.push_back(camera);
  }
  std::sort(cameras.begin(), cameras.end(),
            [](const GroundTruthCamera& a, const GroundTruthCamera& b) { return a.name < b.name; });
  if (cameras.empty()) return Status::NotFound("no .camera files in " + folder.string());
  return cameras;
}

Result<std::vector<GroundTruthCamera>> ReadMiddleburyPar(const fs::path& file) {
  std::ifstream in(file);
  if (!in) return Status::NotFound("cannot open " + file.string());
  int n = 0;
  if (!(in >> n) || n <= 0) return Status::InvalidArgument(file.string() + ": bad view count");
  std::vector<GroundTruthCamera> cameras;
  for (int i = 0; i < n; ++i) {
    GroundTruthCamera camera;
    double v[21];
    if (!(in >> camera.name)) return Status::InvalidArgument(file.string() + ": truncated");
    for (double& x : v) {
      if (!(in >> x))
        return Status::InvalidArgument(file.string() + ": truncated at " + camera.name);
    }
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) camera.K(r, c) = v[3 * r + c];
    }
    Eigen::Matrix3d rotation;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) rotation(r, c) = v[9 + 3 * r + c];
    }
    camera.cam_from_world =
        Rigid3d(NearestRotation(rotation), Eigen::Vector3d(v[18], v[19], v[20]));
    cameras.push_back(camera);
  }
  return cameras;
}

std::string FormatMiddleburyPar(const std::vector<GroundTruthCamera>& cameras) {
  std::ostringstream out;
  out.precision(17);
  out << cameras.size() << "\n";
  for (const GroundTruthCamera& camera : cameras) {
    out << camera.name;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out << " " << camera.K(r, c);
    }
    const Eigen::Matrix3d rotation = camera.cam_from_world.rotation.toRotationMatrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out << " " << rotation(r, c);
    }
    const Eigen::Vector3d& t = camera.cam_from_world.translation;
    out << " " << t.x() << " " << t.y() << " " << t.z() << "\n";
  }
  return out.str();
}

Result<std::vector<GroundTruthCamera>> ReadGroundTruth(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return ReadStrechaCameras(path);
  return ReadMiddleburyPar(path);
}

}  // namespace reconduit
