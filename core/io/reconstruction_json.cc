#include "core/io/reconstruction_json.h"

#include "core/io/file_util.h"
#include "core/io/model_io_util.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

using nlohmann::json;
// Written with the keys in the documented order ("format" and "version" first).
using ordered_json = nlohmann::ordered_json;

constexpr char kFormat[] = "reconduit-reconstruction";

// A malformed value: what() is "<json path>: <problem>". Thrown inside this file only and
// turned into a Status at the API boundary.
class FormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

[[noreturn]] void Fail(const std::string& where, const std::string& problem) {
  throw FormatError(where + ": " + problem);
}

const json& Field(const json& object, const char* key, const std::string& where) {
  if (!object.is_object()) Fail(where, "expected an object");
  auto it = object.find(key);
  if (it == object.end()) Fail(where, std::string("missing \"") + key + "\"");
  return *it;
}

double Number(const json& value, const std::string& where) {
  if (!value.is_number()) Fail(where, "expected a number, found " + value.dump());
  return value.get<double>();
}

int Int(const json& value, const std::string& where) {
  if (!value.is_number_integer()) Fail(where, "expected an integer, found " + value.dump());
  const auto v = value.get<std::int64_t>();
  if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
    Fail(where, "integer out of range");
  }
  return static_cast<int>(v);
}

const json& Array(const json& value, const std::string& where) {
  if (!value.is_array()) Fail(where, "expected an array");
  return value;
}

// An array of exactly `size` numbers, or (size < 0) of an even number of numbers.
std::vector<double> Numbers(const json& value, int size, const std::string& where) {
  Array(value, where);
  if (size >= 0 && value.size() != static_cast<std::size_t>(size)) {
    Fail(where,
         "expected " + std::to_string(size) + " numbers, found " + std::to_string(value.size()));
  }
  if (size < 0 && value.size() % 2 != 0) Fail(where, "expected an even number of values");
  std::vector<double> numbers;
  numbers.reserve(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) {
    numbers.push_back(Number(value[i], where + "[" + std::to_string(i) + "]"));
  }
  return numbers;
}

ordered_json Vector3ToJson(const Eigen::Vector3d& v) {
  return ordered_json::array({v.x(), v.y(), v.z()});
}

Camera CameraFromJson(const json& j, const std::string& where) {
  Camera camera;
  camera.width = Int(Field(j, "width", where), where + ".width");
  camera.height = Int(Field(j, "height", where), where + ".height");
  camera.focal = Number(Field(j, "focal", where), where + ".focal");
  camera.cx = Number(Field(j, "cx", where), where + ".cx");
  camera.cy = Number(Field(j, "cy", where), where + ".cy");
  camera.k1 = Number(Field(j, "k1", where), where + ".k1");
  camera.k2 = Number(Field(j, "k2", where), where + ".k2");
  std::string error;
  if (!camera.Check(&error)) Fail(where, error);
  return camera;
}

RegisteredImage ImageFromJson(const json& j, const std::string& where) {
  RegisteredImage image;
  image.image_id = Int(Field(j, "id", where), where + ".id");
  image.camera_id = Int(Field(j, "camera_id", where), where + ".camera_id");
  const json& name = Field(j, "name", where);
  if (!name.is_string()) Fail(where + ".name", "expected a string");
  image.name = name.get<std::string>();
  const std::vector<double> q = Numbers(Field(j, "rotation", where), 4, where + ".rotation");
  // Assigned without normalising, so the quaternion reads back bit for bit.
  image.cam_from_world.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
  if (std::abs(image.cam_from_world.rotation.norm() - 1.0) > 1e-6) {
    Fail(where + ".rotation", "not a unit quaternion");
  }
  const std::vector<double> t = Numbers(Field(j, "translation", where), 3, where + ".translation");
  image.cam_from_world.translation = Eigen::Vector3d(t[0], t[1], t[2]);
  const std::vector<double> k = Numbers(Field(j, "keypoints", where), -1, where + ".keypoints");
  image.keypoints.reserve(k.size() / 2);
  for (std::size_t i = 0; i < k.size(); i += 2) image.keypoints.emplace_back(k[i], k[i + 1]);
  image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
  return image;
}

Reconstruction FromJson(const json& root) {
  if (!root.is_object()) Fail("(root)", "expected an object");
  const json& format = Field(root, "format", "(root)");
  if (format != kFormat) {
    Fail("format", "expected \"" + std::string(kFormat) + "\", found " + format.dump());
  }
  const int version = Int(Field(root, "version", "(root)"), "version");
  if (version != kReconstructionJsonVersion) {
    Fail("version", "unsupported version " + std::to_string(version) +
                        " (this program reads version " +
                        std::to_string(kReconstructionJsonVersion) + ")");
  }
  Reconstruction rec;
  const json& cameras = Array(Field(root, "cameras", "(root)"), "cameras");
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const std::string where = "cameras[" + std::to_string(i) + "]";
    const int id = Int(Field(cameras[i], "id", where), where + ".id");
    if (id < 0) Fail(where + ".id", "negative id");
    if (!rec.cameras.emplace(id, CameraFromJson(cameras[i], where)).second) {
      Fail(where + ".id", "duplicate camera id " + std::to_string(id));
    }
  }
  const json& images = Array(Field(root, "images", "(root)"), "images");
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::string where = "images[" + std::to_string(i) + "]";
    RegisteredImage image = ImageFromJson(images[i], where);
    if (image.image_id < 0) Fail(where + ".id", "negative id");
    if (!rec.cameras.contains(image.camera_id)) {
      Fail(where + ".camera_id", "unknown camera " + std::to_string(image.camera_id));
    }
    const int id = image.image_id;
    if (!rec.images.emplace(id, std::move(image)).second) {
      Fail(where + ".id", "duplicate image id " + std::to_string(id));
    }
  }
  // Points in increasing id order, as PointIdRestorer needs.
  const json& points = Array(Field(root, "points", "(root)"), "points");
  std::vector<std::pair<int, std::size_t>> order;
  order.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::string where = "points[" + std::to_string(i) + "]";
    order.emplace_back(Int(Field(points[i], "id", where), where + ".id"), i);
  }
  std::sort(order.begin(), order.end());
  model_io::PointIdRestorer restorer(&rec);
  for (const auto& [id, i] : order) {
    const std::string where = "points[" + std::to_string(i) + "]";
    const json& j = points[i];
    const std::vector<double> xyz = Numbers(Field(j, "xyz", where), 3, where + ".xyz");
    const json& rgb = Array(Field(j, "rgb", where), where + ".rgb");
    if (rgb.size() != 3) Fail(where + ".rgb", "expected 3 values");
    Eigen::Matrix<std::uint8_t, 3, 1> color;
    for (int c = 0; c < 3; ++c) {
      const int v = Int(rgb[c], where + ".rgb");
      if (v < 0 || v > 255) Fail(where + ".rgb", "value out of [0, 255]");
      color[c] = static_cast<std::uint8_t>(v);
    }
    const json& error = Field(j, "error", where);
    const double error_px =
        error.is_null() ? std::numeric_limits<double>::infinity() : Number(error, where + ".error");
    const json& track = Array(Field(j, "track", where), where + ".track");
    if (track.size() % 2 != 0 || track.empty()) {
      Fail(where + ".track", "expected a non-empty list of (image_id, keypoint) pairs");
    }
    std::vector<Observation> observations(track.size() / 2);
    for (std::size_t k = 0; k < observations.size(); ++k) {
      observations[k].image_id = Int(track[2 * k], where + ".track");
      observations[k].keypoint = Int(track[2 * k + 1], where + ".track");
    }
    const Status added =
        restorer.Add(id, Eigen::Vector3d(xyz[0], xyz[1], xyz[2]), observations, "");
    if (!added.ok()) Fail(where, added.message());
    Point3D& point = rec.points.at(id);
    point.rgb = color;
    point.error = error_px;
  }
  return rec;
}

}  // namespace

Result<std::string> ReconstructionToJson(const Reconstruction& rec) {
  if (Status s = model_io::CheckReconstruction(rec); !s.ok()) return s;
  ordered_json cameras = ordered_json::array();
  for (const auto& [id, c] : rec.cameras) {
    cameras.push_back({{"id", id},
                       {"width", c.width},
                       {"height", c.height},
                       {"focal", c.focal},
                       {"cx", c.cx},
                       {"cy", c.cy},
                       {"k1", c.k1},
                       {"k2", c.k2}});
  }
  ordered_json images = ordered_json::array();
  for (const auto& [id, image] : rec.images) {
    const Eigen::Quaterniond& q = image.cam_from_world.rotation;
    ordered_json keypoints = ordered_json::array();
    keypoints.get_ref<ordered_json::array_t&>().reserve(2 * image.keypoints.size());
    for (const Eigen::Vector2d& k : image.keypoints) {
      keypoints.push_back(k.x());
      keypoints.push_back(k.y());
    }
    images.push_back({{"id", id},
                      {"camera_id", image.camera_id},
                      {"name", image.name},
                      {"rotation", ordered_json::array({q.w(), q.x(), q.y(), q.z()})},
                      {"translation", Vector3ToJson(image.cam_from_world.translation)},
                      {"keypoints", std::move(keypoints)}});
  }
  ordered_json points = ordered_json::array();
  for (const auto& [id, point] : rec.points) {
    if (point.observations.empty()) {
      return Status::InvalidArgument("point " + std::to_string(id) + " has no observations");
    }
    ordered_json track = ordered_json::array();
    for (const Observation& o : point.observations) {
      track.push_back(o.image_id);
      track.push_back(o.keypoint);
    }
    points.push_back(
        {{"id", id},
         {"xyz", Vector3ToJson(point.xyz_in_world)},
         {"rgb", ordered_json::array({point.rgb[0], point.rgb[1], point.rgb[2]})},
         // nlohmann writes non-finite numbers as null.
         {"error", std::isfinite(point.error) ? ordered_json(point.error) : ordered_json(nullptr)},
         {"track", std::move(track)}});
  }
  ordered_json root = {{"format", kFormat},
                       {"version", kReconstructionJsonVersion},
                       {"cameras", std::move(cameras)},
                       {"images", std::move(images)},
                       {"points", std::move(points)}};
  return root.dump() + "\n";
}

Result<Reconstruction> ReconstructionFromJson(const std::string& text) {
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    return Status::InvalidArgument(std::string("not valid JSON: ") + e.what());
  }
  try {
    return FromJson(root);
  } catch (const FormatError& e) {
    return Status::InvalidArgument(e.what());
  }
}

Status WriteReconstructionJson(const std::filesystem::path& path, const Reconstruction& rec) {
  Result<std::string> text = ReconstructionToJson(rec);
  if (!text.ok()) {
    return Status(text.status().code(), path.string() + ": " + text.status().message());
  }
  return WriteFileAtomically(path, *text);
}

Result<Reconstruction> ReadReconstructionJson(const std::filesystem::path& path) {
  Result<std::string> text = ReadFile(path);
  if (!text.ok()) return text.status();
  Result<Reconstruction> rec = ReconstructionFromJson(*text);
  if (!rec.ok()) {
    return Status(rec.status().code(), path.string() + ": " + rec.status().message());
  }
  return rec;
}

}  // namespace reconduit
