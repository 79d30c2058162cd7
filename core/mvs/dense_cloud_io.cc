#include "core/mvs/dense_cloud_io.h"

#include "core/io/file_util.h"

#include <bit>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace reconduit {
namespace {

constexpr char kHeaderStart[] =
    "ply\n"
    "format binary_little_endian 1.0\n"
    "comment Reconduit dense point cloud (visibility: positions in cameras.json images)\n";
constexpr char kHeaderProperties[] =
    "property float x\n"
    "property float y\n"
    "property float z\n"
    "property float nx\n"
    "property float ny\n"
    "property float nz\n"
    "property uchar red\n"
    "property uchar green\n"
    "property uchar blue\n"
    "property list uchar int visibility\n"
    "end_header\n";

static_assert(std::endian::native == std::endian::little, "PLY is written little-endian");

template <typename T>
void Append(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
bool Take(const std::string& in, std::size_t* at, T* value) {
  if (in.size() - *at < sizeof(T)) return false;
  std::memcpy(value, in.data() + *at, sizeof(T));
  *at += sizeof(T);
  return true;
}

}  // namespace

Status WriteDenseCloudPly(const std::filesystem::path& path, const DenseCloud& cloud) {
  const std::size_t n = cloud.size();
  if (cloud.normals.size() != n || cloud.colors.size() != n ||
      cloud.visibility_offsets.size() != n + 1 ||
      cloud.visibility_offsets.back() != cloud.visibility.size()) {
    return Status::InvalidArgument("dense cloud arrays disagree in size");
  }
  std::string out = kHeaderStart;
  out += "element vertex " + std::to_string(n) + "\n";
  out += kHeaderProperties;
  out.reserve(out.size() + n * 28 + cloud.visibility.size() * 4);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) Append(&out, cloud.positions[i][c]);
    for (int c = 0; c < 3; ++c) Append(&out, cloud.normals[i][c]);
    for (int c = 0; c < 3; ++c) Append(&out, cloud.colors[i][c]);
    const std::uint32_t begin = cloud.visibility_offsets[i];
    const std::uint32_t count = cloud.visibility_offsets[i + 1] - begin;
    if (count > 255) {
      return Status::InvalidArgument("point " + std::to_string(i) + " is seen by " +
                                     std::to_string(count) + " photos; at most 255 are written");
    }
    Append(&out, static_cast<std::uint8_t>(count));
    for (std::uint32_t k = 0; k < count; ++k)
      Append(&out, static_cast<std::int32_t>(cloud.visibility[begin + k]));
  }
  return WriteFileAtomically(path, out);
}

Result<DenseCloud> ReadDenseCloudPly(const std::filesystem::path& path) {
  auto text = ReadFile(path);
  if (!text.ok()) return text.status();
  const std::string& in = *text;
  const std::string name = path.filename().string();
  const std::size_t header_end = in.find("end_header\n");
  if (header_end == std::string::npos || in.rfind(kHeaderStart, 0) != 0)
    return Status::InvalidArgument(name + ": not a Reconduit dense PLY");
  const std::size_t start = sizeof(kHeaderStart) - 1;
  std::size_t at = header_end + std::strlen("end_header\n");
  std::istringstream header(in.substr(start, at - start));
  std::string element, vertex;
  std::size_t n = 0;
  header >> element >> vertex >> n;
  header.ignore(1);
  const std::string rest(std::istreambuf_iterator<char>(header), {});
  if (element != "element" || vertex != "vertex" || rest != kHeaderProperties)
    return Status::InvalidArgument(name + ": unexpected PLY header (not written by Reconduit)");

  const std::size_t min_record = 28;
  if (n > (in.size() - at) / min_record)
    return Status::InvalidArgument(name + ": truncated (" + std::to_string(n) + " points)");
  DenseCloud cloud;
  cloud.positions.resize(n);
  cloud.normals.resize(n);
  cloud.colors.resize(n);
  cloud.visibility_offsets.reserve(n + 1);
  for (std::size_t i = 0; i < n; ++i) {
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok = ok && Take(in, &at, &cloud.positions[i][c]);
    for (int c = 0; c < 3; ++c) ok = ok && Take(in, &at, &cloud.normals[i][c]);
    for (int c = 0; c < 3; ++c) ok = ok && Take(in, &at, &cloud.colors[i][c]);
    std::uint8_t count = 0;
    ok = ok && Take(in, &at, &count);
    for (int k = 0; ok && k < count; ++k) {
      std::int32_t id = 0;
      ok = Take(in, &at, &id);
      cloud.visibility.push_back(id);
    }
    if (!ok) return Status::InvalidArgument(name + ": truncated at point " + std::to_string(i));
    cloud.visibility_offsets.push_back(static_cast<std::uint32_t>(cloud.visibility.size()));
  }
  if (at != in.size()) return Status::InvalidArgument(name + ": bytes after the last point");
  return cloud;
}

}  // namespace reconduit
