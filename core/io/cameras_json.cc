#include "core/io/cameras_json.h"

#include "core/io/file_util.h"
#include "core/io/model_io_util.h"

#include <nlohmann/json.hpp>

namespace reconduit {
namespace {

// ordered_json keeps the keys in the documented order for readers of the file.
using json = nlohmann::ordered_json;

constexpr char kCoordinateFrame[] =
    "rotation R is world-to-camera and center c is the camera centre in world coordinates: "
    "x_cam = R (X - c). The camera looks down +z with x to the right and y down. Projection: "
    "(x, y) = (x_cam / z_cam, y_cam / z_cam), r2 = x^2 + y^2, s = 1 + k1 r2 + k2 r2^2, "
    "pixel = (focal s x + cx, focal s y + cy) with [cx, cy] = principal_point. Pixels are those "
    "of the original image (width x height) with the centre of the top-left pixel at (0, 0), so "
    "the image centre is ((width - 1) / 2, (height - 1) / 2); add 0.5 for conventions with pixel "
    "centres at half-integers (COLMAP). The world frame is the reconstruction's: right-handed, "
    "metric up to one global scale.";

}  // namespace

Result<std::string> CamerasJson(const Reconstruction& rec,
                                const std::vector<std::string>& unregistered_names) {
  if (Status s = model_io::CheckReconstruction(rec); !s.ok()) return s;
  json images = json::array();
  for (const auto& [id, image] : rec.images) {
    const Camera& camera = rec.cameras.at(image.camera_id);
    const Eigen::Matrix3d r = image.cam_from_world.rotation.toRotationMatrix();
    const Eigen::Vector3d center = -r.transpose() * image.cam_from_world.translation;
    json rotation = json::array();
    for (int row = 0; row < 3; ++row) {
      rotation.push_back(json::array({r(row, 0), r(row, 1), r(row, 2)}));
    }
    images.push_back({{"name", image.name},
                      {"width", camera.width},
                      {"height", camera.height},
                      {"focal", camera.focal},
                      {"principal_point", json::array({camera.cx, camera.cy})},
                      {"k1", camera.k1},
                      {"k2", camera.k2},
                      {"rotation", std::move(rotation)},
                      {"center", json::array({center.x(), center.y(), center.z()})},
                      {"registered", true}});
  }
  const json root = {{"version", kCamerasJsonVersion},
                     {"coordinate_frame", kCoordinateFrame},
                     {"images", std::move(images)},
                     {"unregistered", unregistered_names}};
  return root.dump(2) + "\n";
}

Status WriteCamerasJson(const std::filesystem::path& path,
                        const Reconstruction& rec,
                        const std::vector<std::string>& unregistered_names) {
  Result<std::string> text = CamerasJson(rec, unregistered_names);
  if (!text.ok()) return text.status();
  return WriteFileAtomically(path, *text);
}

}  // namespace reconduit
