#include "core/io/colmap_text.h"

#include "core/io/file_util.h"
#include "core/io/model_io_util.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using model_io::AppendDouble;
using model_io::AppendInt;
using model_io::ParseDouble;
using model_io::ParseInt;
using model_io::SplitWhitespace;

// Our pixel centres are at integers, COLMAP's at +0.5.
constexpr double kPixelShift = 0.5;

// Our id -> COLMAP's id.
long long ToColmapId(int id) { return static_cast<long long>(id) + 1; }

// ------------------------------------------------------------------------------------------
// Writing

std::string CamerasText(const Reconstruction& rec) {
  std::string out =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: " +
      std::to_string(rec.cameras.size()) + "\n";
  for (const auto& [id, camera] : rec.cameras) {
    AppendInt(ToColmapId(id), &out);
    out += " RADIAL ";
    AppendInt(camera.width, &out);
    out += ' ';
    AppendInt(camera.height, &out);
    for (double v :
         {camera.focal, camera.cx + kPixelShift, camera.cy + kPixelShift, camera.k1, camera.k2}) {
      out += ' ';
      AppendDouble(v, &out);
    }
    out += '\n';
  }
  return out;
}

std::string ImagesText(const Reconstruction& rec) {
  std::size_t observations = 0;
  for (const auto& [id, image] : rec.images) observations += image.NumPoints();
  const double mean =
      rec.images.empty() ? 0.0 : static_cast<double>(observations) / rec.images.size();
  std::string out =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      "# Number of images: " +
      std::to_string(rec.images.size()) + ", mean observations per image: ";
  AppendDouble(mean, &out);
  out += '\n';
  for (const auto& [id, image] : rec.images) {
    const Eigen::Quaterniond& q = image.cam_from_world.rotation;
    const Eigen::Vector3d& t = image.cam_from_world.translation;
    AppendInt(ToColmapId(id), &out);
    for (double v : {q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z()}) {
      out += ' ';
      AppendDouble(v, &out);
    }
    out += ' ';
    AppendInt(ToColmapId(image.camera_id), &out);
    out += ' ';
    out += image.name;
    out += '\n';
    for (std::size_t k = 0; k < image.keypoints.size(); ++k) {
      if (k > 0) out += ' ';
      AppendDouble(image.keypoints[k].x() + kPixelShift, &out);
      out += ' ';
      AppendDouble(image.keypoints[k].y() + kPixelShift, &out);
      out += ' ';
      const int point_id = image.point_for_keypoint[k];
      AppendInt(point_id == kInvalidId ? -1 : ToColmapId(point_id), &out);
    }
    out += '\n';
  }
  return out;
}

std::string Points3DText(const Reconstruction& rec) {
  const double mean_track =
      rec.points.empty() ? 0.0 : static_cast<double>(rec.NumObservations()) / rec.points.size();
  std::string out =
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      "# Number of points: " +
      std::to_string(rec.points.size()) + ", mean track length: ";
  AppendDouble(mean_track, &out);
  out += '\n';
  for (const auto& [id, point] : rec.points) {
    AppendInt(ToColmapId(id), &out);
    for (double v : {point.xyz_in_world.x(), point.xyz_in_world.y(), point.xyz_in_world.z()}) {
      out += ' ';
      AppendDouble(v, &out);
    }
    for (int c = 0; c < 3; ++c) {
      out += ' ';
      AppendInt(point.rgb[c], &out);
    }
    out += ' ';
    AppendDouble(point.error, &out);
    for (const Observation& o : point.observations) {
      out += ' ';
      AppendInt(ToColmapId(o.image_id), &out);
      out += ' ';
      AppendInt(o.keypoint, &out);
    }
    out += '\n';
  }
  return out;
}

// ------------------------------------------------------------------------------------------
// Reading

// The lines of a file, with their 1-based numbers for messages.
struct TextFile {
  std::string name;  // For messages: "cameras.txt".
  std::string text;
  std::vector<std::string_view> lines;

  std::string Where(std::size_t line_index) const {
    return name + ":" + std::to_string(line_index + 1) + ": ";
  }
  // True for lines the format ignores.
  bool Skip(std::size_t i) const {
    const auto tokens = SplitWhitespace(lines[i]);
    return tokens.empty() || tokens.front().front() == '#';
  }
};

Result<TextFile> LoadText(const fs::path& folder, const std::string& name) {
  Result<std::string> text = ReadFile(folder / name);
  if (!text.ok()) return text.status();
  TextFile file;
  file.name = name;
  file.text = std::move(*text);
  std::string_view rest = file.text;
  while (!rest.empty()) {
    const std::size_t end = rest.find('\n');
    file.lines.push_back(rest.substr(0, end));
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + 1);
  }
  return file;
}

// Our id from a COLMAP id token (>= 1).
bool ParseColmapId(std::string_view token, int* id) {
  int colmap_id = 0;
  if (!ParseInt(token, &colmap_id) || colmap_id < 1) return false;
  *id = colmap_id - 1;
  return true;
}

Status ParseCameras(const TextFile& file, Reconstruction* rec) {
  for (std::size_t i = 0; i < file.lines.size(); ++i) {
    if (file.Skip(i)) continue;
    const auto tokens = SplitWhitespace(file.lines[i]);
    const std::string where = file.Where(i);
    if (tokens.size() < 4) return Status::InvalidArgument(where + "expected at least 4 columns");
    int id = 0;
    Camera camera;
    if (!ParseColmapId(tokens[0], &id)) {
      return Status::InvalidArgument(where + "bad CAMERA_ID '" + std::string(tokens[0]) + "'");
    }
    if (!ParseInt(tokens[2], &camera.width) || !ParseInt(tokens[3], &camera.height)) {
      return Status::InvalidArgument(where + "bad WIDTH or HEIGHT");
    }
    const std::string_view model = tokens[1];
    std::size_t num_params = 0;
    if (model == "SIMPLE_PINHOLE") {
      num_params = 3;
    } else if (model == "SIMPLE_RADIAL") {
      num_params = 4;
    } else if (model == "PINHOLE" || model == "RADIAL") {
      num_params = 4 + (model == "RADIAL");
    } else {
      return Status::InvalidArgument(where + "unsupported camera model " + std::string(model) +
                                     " (supported: SIMPLE_PINHOLE, PINHOLE with fx = fy, "
                                     "SIMPLE_RADIAL, RADIAL)");
    }
    if (tokens.size() != 4 + num_params) {
      return Status::InvalidArgument(where + std::string(model) + " needs " +
                                     std::to_string(4 + num_params) + " columns, found " +
                                     std::to_string(tokens.size()));
    }
    std::vector<double> p(num_params);
    for (std::size_t k = 0; k < num_params; ++k) {
      if (!ParseDouble(tokens[4 + k], &p[k])) {
        return Status::InvalidArgument(where + "bad parameter '" + std::string(tokens[4 + k]) +
                                       "'");
      }
    }
    camera.focal = p[0];
    std::size_t next = 1;
    if (model == "PINHOLE") {
      if (p[1] != p[0]) {
        return Status::InvalidArgument(where + "PINHOLE with fx != fy cannot be represented");
      }
      next = 2;
    }
    camera.cx = p[next] - kPixelShift;
    camera.cy = p[next + 1] - kPixelShift;
    if (num_params > next + 2) camera.k1 = p[next + 2];
    if (num_params > next + 3) camera.k2 = p[next + 3];
    std::string error;
    if (!camera.Check(&error)) return Status::InvalidArgument(where + error);
    if (!rec->cameras.emplace(id, camera).second) {
      return Status::InvalidArgument(where + "duplicate CAMERA_ID");
    }
  }
  return Status::Ok();
}

// Fills rec->images; `expected_points[image_id][k]` is the point id images.txt gives for
// keypoint k (kInvalidId for -1), checked against the tracks once the points are read.
Status ParseImages(const TextFile& file,
                   Reconstruction* rec,
                   std::map<int, std::vector<int>>* expected_points) {
  for (std::size_t i = 0; i < file.lines.size(); ++i) {
    if (file.Skip(i)) continue;
    const std::string_view line = file.lines[i];
    const auto tokens = SplitWhitespace(line);
    const std::string where = file.Where(i);
    if (tokens.size() < 10) {
      return Status::InvalidArgument(where +
                                     "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID "
                                     "NAME, found " +
                                     std::to_string(tokens.size()) + " columns");
    }
    RegisteredImage image;
    double v[7];
    for (int k = 0; k < 7; ++k) {
      if (!ParseDouble(tokens[1 + k], &v[k])) {
        return Status::InvalidArgument(where + "bad pose value '" + std::string(tokens[1 + k]) +
                                       "'");
      }
    }
    if (!ParseColmapId(tokens[0], &image.image_id) || !ParseColmapId(tokens[8], &image.camera_id)) {
      return Status::InvalidArgument(where + "bad IMAGE_ID or CAMERA_ID");
    }
    if (!rec->cameras.contains(image.camera_id)) {
      return Status::InvalidArgument(where + "unknown CAMERA_ID " + std::string(tokens[8]));
    }
    const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
    if (!std::isfinite(q.norm()) || q.norm() < 0.5 || q.norm() > 2.0) {
      return Status::InvalidArgument(where + "the quaternion is not a rotation");
    }
    image.cam_from_world = Rigid3d(q, Eigen::Vector3d(v[4], v[5], v[6]));
    // NAME is the rest of the line (may contain spaces).
    std::string_view name = line.substr(tokens[9].data() - line.data());
    while (!name.empty() && (name.back() == ' ' || name.back() == '\t' || name.back() == '\r')) {
      name.remove_suffix(1);
    }
    image.name = std::string(name);

    // The next line, whatever it holds, is the POINTS2D line (empty for no keypoints).
    if (++i >= file.lines.size()) {
      return Status::InvalidArgument(where + "missing the POINTS2D line of the image");
    }
    const auto points = SplitWhitespace(file.lines[i]);
    if (points.size() % 3 != 0) {
      return Status::InvalidArgument(file.Where(i) +
                                     "POINTS2D needs 3 columns (X Y POINT3D_ID) per keypoint, "
                                     "found " +
                                     std::to_string(points.size()) + " values");
    }
    std::vector<int>& expected = (*expected_points)[image.image_id];
    for (std::size_t k = 0; k < points.size(); k += 3) {
      double x = 0.0, y = 0.0;
      long long point_id = 0;
      const auto parsed = std::from_chars(points[k + 2].data(),
                                          points[k + 2].data() + points[k + 2].size(), point_id);
      if (!ParseDouble(points[k], &x) || !ParseDouble(points[k + 1], &y) ||
          parsed.ec != std::errc() || parsed.ptr != points[k + 2].data() + points[k + 2].size() ||
          point_id < -1 || point_id == 0 || point_id > std::numeric_limits<int>::max()) {
        return Status::InvalidArgument(file.Where(i) + "bad keypoint " + std::to_string(k / 3));
      }
      image.keypoints.emplace_back(x - kPixelShift, y - kPixelShift);
      expected.push_back(point_id == -1 ? kInvalidId : static_cast<int>(point_id - 1));
    }
    image.point_for_keypoint.assign(image.keypoints.size(), kInvalidId);
    const int id = image.image_id;
    if (!rec->images.emplace(id, std::move(image)).second) {
      return Status::InvalidArgument(where + "duplicate IMAGE_ID");
    }
  }
  return Status::Ok();
}

struct ParsedPoint {
  int id = 0;
  Eigen::Vector3d xyz;
  Eigen::Matrix<std::uint8_t, 3, 1> rgb;
  double error = 0.0;
  std::vector<Observation> track;
  std::size_t line = 0;
};

Status ParsePoints(const TextFile& file, Reconstruction* rec) {
  std::vector<ParsedPoint> points;
  for (std::size_t i = 0; i < file.lines.size(); ++i) {
    if (file.Skip(i)) continue;
    const auto tokens = SplitWhitespace(file.lines[i]);
    const std::string where = file.Where(i);
    if (tokens.size() < 10 || (tokens.size() - 8) % 2 != 0) {
      return Status::InvalidArgument(
          where +
          "expected POINT3D_ID X Y Z R G B ERROR and (IMAGE_ID, POINT2D_IDX) pairs, found " +
          std::to_string(tokens.size()) + " columns");
    }
    ParsedPoint point;
    point.line = i;
    if (!ParseColmapId(tokens[0], &point.id)) {
      return Status::InvalidArgument(where + "bad POINT3D_ID");
    }
    for (int k = 0; k < 3; ++k) {
      int c = 0;
      if (!ParseDouble(tokens[1 + k], &point.xyz[k]) || !ParseInt(tokens[4 + k], &c) || c < 0 ||
          c > 255) {
        return Status::InvalidArgument(where + "bad position or colour");
      }
      point.rgb[k] = static_cast<std::uint8_t>(c);
    }
    if (!ParseDouble(tokens[7], &point.error)) {
      return Status::InvalidArgument(where + "bad ERROR");
    }
    for (std::size_t k = 8; k < tokens.size(); k += 2) {
      Observation o;
      if (!ParseColmapId(tokens[k], &o.image_id) || !ParseInt(tokens[k + 1], &o.keypoint)) {
        return Status::InvalidArgument(where + "bad track element " + std::to_string((k - 8) / 2));
      }
      point.track.push_back(o);
    }
    points.push_back(std::move(point));
  }
  std::sort(points.begin(), points.end(),
            [](const ParsedPoint& a, const ParsedPoint& b) { return a.id < b.id; });
  model_io::PointIdRestorer restorer(rec);
  for (const ParsedPoint& p : points) {
    if (Status s = restorer.Add(p.id, p.xyz, p.track, file.Where(p.line)); !s.ok()) return s;
    Point3D& point = rec->points.at(p.id);
    point.rgb = p.rgb;
    point.error = p.error;
  }
  return Status::Ok();
}

}  // namespace

Status WriteColmapText(const fs::path& folder, const Reconstruction& rec) {
  if (Status s = model_io::CheckReconstruction(rec); !s.ok()) return s;
  for (const auto& [id, image] : rec.images) {
    if (image.name.empty() || image.name.find_first_of("\r\n") != std::string::npos ||
        image.name.front() == ' ' || image.name.front() == '\t') {
      return Status::InvalidArgument("image " + std::to_string(id) + ": name '" + image.name +
                                     "' is empty, starts with a blank or holds a line break");
    }
  }
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) {
    return Status::Internal("cannot create '" + folder.string() + "': " + error.message());
  }
  if (Status s = WriteFileAtomically(folder / "cameras.txt", CamerasText(rec)); !s.ok()) return s;
  if (Status s = WriteFileAtomically(folder / "images.txt", ImagesText(rec)); !s.ok()) return s;
  return WriteFileAtomically(folder / "points3D.txt", Points3DText(rec));
}

Result<Reconstruction> ReadColmapText(const fs::path& folder) {
  Result<TextFile> cameras = LoadText(folder, "cameras.txt");
  if (!cameras.ok()) return cameras.status();
  Result<TextFile> images = LoadText(folder, "images.txt");
  if (!images.ok()) return images.status();
  Result<TextFile> points = LoadText(folder, "points3D.txt");
  if (!points.ok()) return points.status();

  Reconstruction rec;
  std::map<int, std::vector<int>> expected_points;
  if (Status s = ParseCameras(*cameras, &rec); !s.ok()) return s;
  if (Status s = ParseImages(*images, &rec, &expected_points); !s.ok()) return s;
  if (Status s = ParsePoints(*points, &rec); !s.ok()) return s;
  for (const auto& [image_id, expected] : expected_points) {
    const std::vector<int>& actual = rec.images.at(image_id).point_for_keypoint;
    for (std::size_t k = 0; k < expected.size(); ++k) {
      if (expected[k] != actual[k]) {
        return Status::InvalidArgument(
            "images.txt: image " + std::to_string(ToColmapId(image_id)) + " keypoint " +
            std::to_string(k) + " names POINT3D_ID " +
            std::to_string(expected[k] == kInvalidId ? -1 : ToColmapId(expected[k])) +
            " but points3D.txt says " +
            std::to_string(actual[k] == kInvalidId ? -1 : ToColmapId(actual[k])));
      }
    }
  }
  return rec;
}

}  // namespace reconduit
