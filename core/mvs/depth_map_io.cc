#include "core/mvs/depth_map_io.h"

#include "core/io/file_util.h"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace reconduit {
namespace {

constexpr char kMagic[4] = {'R', 'C', 'D', 'M'};
constexpr std::int32_t kVersion = 1;

void Append(std::string* out, const void* data, std::size_t bytes) {
  out->append(static_cast<const char*>(data), bytes);
}

void AppendRows(std::string* out, const cv::Mat& mat) {
  const std::size_t row_bytes = mat.cols * mat.elemSize();
  for (int y = 0; y < mat.rows; ++y) Append(out, mat.ptr(y), row_bytes);
}

bool ReadRows(const std::string& in, std::size_t* offset, cv::Mat* mat) {
  const std::size_t bytes = mat->total() * mat->elemSize();
  if (in.size() < *offset + bytes) return false;
  const std::size_t row_bytes = mat->cols * mat->elemSize();
  for (int y = 0; y < mat->rows; ++y)
    std::memcpy(mat->ptr(y), in.data() + *offset + y * row_bytes, row_bytes);
  *offset += bytes;
  return true;
}

}  // namespace

Status WriteDepthMapBinary(const std::filesystem::path& path, const DepthMap& map) {
  if (map.depth.type() != CV_32FC1 || map.normal.type() != CV_32FC3 ||
      map.cost.type() != CV_32FC1 || map.normal.size() != map.depth.size() ||
      map.cost.size() != map.depth.size()) {
    return Status::InvalidArgument("depth map with inconsistent layers: " + path.string());
  }
  std::string out;
  out.reserve(32 + map.depth.total() * 20);
  Append(&out, kMagic, 4);
  const std::int32_t header[3] = {kVersion, map.depth.cols, map.depth.rows};
  Append(&out, header, sizeof(header));
  AppendRows(&out, map.depth);
  AppendRows(&out, map.normal);
  AppendRows(&out, map.cost);
  return WriteFileAtomically(path, out);
}

Result<DepthMap> ReadDepthMapBinary(const std::filesystem::path& path) {
  Result<std::string> in = ReadFile(path);
  if (!in.ok()) return in.status();
  std::int32_t header[3] = {0, 0, 0};
  if (in->size() < 4 + sizeof(header) || std::memcmp(in->data(), kMagic, 4) != 0) {
    return Status::InvalidArgument("not a depth map: " + path.string());
  }
  std::memcpy(header, in->data() + 4, sizeof(header));
  if (header[0] != kVersion || header[1] <= 0 || header[2] <= 0 || header[1] > 100000 ||
      header[2] > 100000) {
    return Status::InvalidArgument("unsupported depth map header: " + path.string());
  }
  DepthMap map;
  map.depth.create(header[2], header[1], CV_32FC1);
  map.normal.create(header[2], header[1], CV_32FC3);
  map.cost.create(header[2], header[1], CV_32FC1);
  std::size_t offset = 4 + sizeof(header);
  if (!ReadRows(*in, &offset, &map.depth) || !ReadRows(*in, &offset, &map.normal) ||
      !ReadRows(*in, &offset, &map.cost) || offset != in->size()) {
    return Status::InvalidArgument("truncated depth map: " + path.string());
  }
  return map;
}

Status WriteDepthPng(const std::filesystem::path& png_path,
                     const std::filesystem::path& json_path,
                     const cv::Mat& depth,
                     const Camera& camera,
                     const Rigid3d& cam_from_world) {
  if (depth.type() != CV_32FC1 || depth.cols != camera.width || depth.rows != camera.height) {
    return Status::InvalidArgument("depth map does not match its camera: " + png_path.string());
  }
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      const float d = depth.at<float>(y, x);
      if (d <= 0.0f) continue;
      lo = std::min<double>(lo, d);
      hi = std::max<double>(hi, d);
    }
  }
  if (hi <= 0.0) lo = hi = 0.0;
  const double range = hi > lo ? hi - lo : 1.0;
  cv::Mat png(depth.size(), CV_16UC1, cv::Scalar(0));
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      const float d = depth.at<float>(y, x);
      if (d <= 0.0f) continue;
      png.at<std::uint16_t>(y, x) =
          static_cast<std::uint16_t>(1 + std::lround((d - lo) / range * 65534.0));
    }
  }
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", png, bytes)) {
    return Status::Internal("cannot encode " + png_path.string());
  }
  const Eigen::Quaterniond& q = cam_from_world.rotation;
  const nlohmann::json json = {
      {"format", "reconduit depth map 1"},
      {"encoding",
       "16-bit PNG; 0 = no depth, else depth = depth_min + (value - 1) / 65534 * (depth_max - "
       "depth_min), depth = z in the camera frame"},
      {"width", depth.cols},
      {"height", depth.rows},
      {"depth_min", lo},
      {"depth_max", hi},
      {"camera",
       {{"model", "pinhole"},
        {"width", camera.width},
        {"height", camera.height},
        {"focal", camera.focal},
        {"cx", camera.cx},
        {"cy", camera.cy}}},
      {"cam_from_world",
       {{"rotation_wxyz", {q.w(), q.x(), q.y(), q.z()}},
        {"translation",
         {cam_from_world.translation.x(), cam_from_world.translation.y(),
          cam_from_world.translation.z()}}}}};
  if (Status s = WriteFileAtomically(
          png_path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
      !s.ok()) {
    return s;
  }
  return WriteFileAtomically(json_path, json.dump(2) + "\n");
}

Result<cv::Mat> ReadDepthPng(const std::filesystem::path& png_path,
                             const std::filesystem::path& json_path) {
  Result<std::string> text = ReadFile(json_path);
  if (!text.ok()) return text.status();
  const nlohmann::json json = nlohmann::json::parse(*text, nullptr, false);
  if (json.is_discarded() || !json.contains("depth_min") || !json.contains("depth_max")) {
    return Status::InvalidArgument("not a depth map description: " + json_path.string());
  }
  const cv::Mat png = cv::imread(png_path.string(), cv::IMREAD_UNCHANGED);
  if (png.empty() || png.type() != CV_16UC1) {
    return Status::InvalidArgument("not a 16-bit depth PNG: " + png_path.string());
  }
  const double lo = json["depth_min"].get<double>(), hi = json["depth_max"].get<double>();
  cv::Mat depth(png.size(), CV_32FC1, cv::Scalar(0));
  for (int y = 0; y < png.rows; ++y) {
    for (int x = 0; x < png.cols; ++x) {
      const std::uint16_t v = png.at<std::uint16_t>(y, x);
      if (v == 0) continue;
      depth.at<float>(y, x) = static_cast<float>(lo + (v - 1) / 65534.0 * (hi - lo));
    }
  }
  return depth;
}

}  // namespace reconduit
