#include "core/io/bundler.h"

#include "core/io/file_util.h"
#include "core/io/model_io_util.h"

#include <map>
#include <string>
#include <system_error>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using model_io::AppendDouble;
using model_io::AppendInt;

void AppendRow(double a, double b, double c, std::string* out) {
  AppendDouble(a, out);
  *out += ' ';
  AppendDouble(b, out);
  *out += ' ';
  AppendDouble(c, out);
  *out += '\n';
}

}  // namespace

Status WriteBundler(const fs::path& folder, const Reconstruction& rec) {
  if (Status s = model_io::CheckReconstruction(rec); !s.ok()) return s;
  // Camera index of each image: its rank in increasing image id (std::map order).
  std::map<int, int> camera_index;
  std::string list;
  for (const auto& [id, image] : rec.images) {
    if (image.name.empty() || image.name.find_first_of("\r\n") != std::string::npos) {
      return Status::InvalidArgument("image " + std::to_string(id) + ": name '" + image.name +
                                     "' is empty or holds a line break");
    }
    camera_index.emplace(id, static_cast<int>(camera_index.size()));
    list += image.name;
    list += '\n';
  }

  std::string out = "# Bundle file v0.3\n";
  AppendInt(static_cast<long long>(rec.images.size()), &out);
  out += ' ';
  AppendInt(static_cast<long long>(rec.points.size()), &out);
  out += '\n';
  // D = diag(1, -1, -1) turns our camera frame (y down, looking down +z) into Bundler's
  // (y up, looking down -z).
  const Eigen::Matrix3d flip = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  for (const auto& [id, image] : rec.images) {
    const Camera& camera = rec.cameras.at(image.camera_id);
    AppendRow(camera.focal, camera.k1, camera.k2, &out);
    const Eigen::Matrix3d r = flip * image.cam_from_world.rotation.toRotationMatrix();
    const Eigen::Vector3d t = flip * image.cam_from_world.translation;
    for (int row = 0; row < 3; ++row) AppendRow(r(row, 0), r(row, 1), r(row, 2), &out);
    AppendRow(t.x(), t.y(), t.z(), &out);
  }
  for (const auto& [id, point] : rec.points) {
    AppendRow(point.xyz_in_world.x(), point.xyz_in_world.y(), point.xyz_in_world.z(), &out);
    for (int c = 0; c < 3; ++c) {
      AppendInt(point.rgb[c], &out);
      out += c < 2 ? ' ' : '\n';
    }
    AppendInt(static_cast<long long>(point.observations.size()), &out);
    for (const Observation& o : point.observations) {
      const RegisteredImage& image = rec.images.at(o.image_id);
      const Camera& camera = rec.cameras.at(image.camera_id);
      const Eigen::Vector2d& pixel = image.keypoints[o.keypoint];
      // Centred at the image centre, y up (see bundler.h).
      const double x = pixel.x() - (camera.width - 1) / 2.0;
      const double y = (camera.height - 1) / 2.0 - pixel.y();
      out += ' ';
      AppendInt(camera_index.at(o.image_id), &out);
      out += ' ';
      AppendInt(o.keypoint, &out);
      out += ' ';
      AppendDouble(x, &out);
      out += ' ';
      AppendDouble(y, &out);
    }
    out += '\n';
  }

  std::error_code error;
  fs::create_directories(folder, error);
  if (error) {
    return Status::Internal("cannot create '" + folder.string() + "': " + error.message());
  }
  if (Status s = WriteFileAtomically(folder / "list.txt", list); !s.ok()) return s;
  return WriteFileAtomically(folder / "bundle.out", out);
}

}  // namespace reconduit
