#include "core/io/ply.h"

#include "core/io/file_util.h"

#include <bit>
#include <fstream>
#include <random>
#include <system_error>
#include <unistd.h>

namespace reconduit {
namespace {

namespace fs = std::filesystem;

// Appends the bytes of `bits` least significant first, whatever the host's byte order.
template <typename UInt>
void AppendLittleEndian(UInt bits, std::string* out) {
  for (std::size_t i = 0; i < sizeof(UInt); ++i) {
    out->push_back(static_cast<char>((bits >> (8 * i)) & 0xff));
  }
}

void AppendFloat(float value, std::string* out) {
  AppendLittleEndian(std::bit_cast<std::uint32_t>(value), out);
}

void AppendDouble(double value, std::string* out) {
  AppendLittleEndian(std::bit_cast<std::uint64_t>(value), out);
}

// Flush to the file once the buffer holds this much.
constexpr std::size_t kChunkBytes = 1 << 20;

}  // namespace

std::string PointCloudPlyHeader(std::size_t num_points,
                                bool has_normals,
                                const PlyOptions& options) {
  const char* type = options.double_precision ? "double" : "float";
  std::string header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment Reconduit point cloud\n"
      "element vertex " +
      std::to_string(num_points) + "\n";
  for (const char* axis : {"x", "y", "z"}) {
    header += std::string("property ") + type + " " + axis + "\n";
  }
  if (has_normals) {
    header += "property float nx\nproperty float ny\nproperty float nz\n";
  }
  header += "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  return header;
}

Status WritePointCloudPly(const fs::path& path,
                          const PointCloud& cloud,
                          const PlyOptions& options) {
  const std::size_t n = cloud.positions.size();
  if (cloud.colors.size() != n || (!cloud.normals.empty() && cloud.normals.size() != n)) {
    return Status::InvalidArgument("point cloud with " + std::to_string(n) + " positions, " +
                                   std::to_string(cloud.colors.size()) + " colours and " +
                                   std::to_string(cloud.normals.size()) + " normals");
  }
  const bool has_normals = !cloud.normals.empty();
  std::random_device random;
  const fs::path temp =
      path.string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(random());
  std::ofstream file(temp, std::ios::binary | std::ios::trunc);
  if (!file) return Status::Internal("cannot create '" + temp.string() + "'");

  std::string buffer = PointCloudPlyHeader(n, has_normals, options);
  buffer.reserve(kChunkBytes + 64);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = cloud.positions[i];
    for (int k = 0; k < 3; ++k) {
      if (options.double_precision) {
        AppendDouble(p[k], &buffer);
      } else {
        AppendFloat(static_cast<float>(p[k]), &buffer);
      }
    }
    if (has_normals) {
      for (int k = 0; k < 3; ++k) AppendFloat(cloud.normals[i][k], &buffer);
    }
    for (int k = 0; k < 3; ++k) buffer.push_back(static_cast<char>(cloud.colors[i][k]));
    if (buffer.size() >= kChunkBytes) {
      file.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      buffer.clear();
    }
  }
  file.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  file.close();
  if (!file) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    return Status::Internal("cannot write '" + temp.string() + "'");
  }
  Status committed = CommitFile(temp, path);
  if (!committed.ok()) {
    std::error_code ignored;
    fs::remove(temp, ignored);
  }
  return committed;
}

PointCloud PointCloudFromReconstruction(const Reconstruction& rec) {
  PointCloud cloud;
  cloud.positions.reserve(rec.points.size());
  cloud.colors.reserve(rec.points.size());
  for (const auto& [id, point] : rec.points) {
    cloud.positions.push_back(point.xyz_in_world);
    cloud.colors.push_back(point.rgb);
  }
  return cloud;
}

}  // namespace reconduit
