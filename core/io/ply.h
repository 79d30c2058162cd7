// Coloured point clouds as binary little-endian PLY (sparse.ply, dense.ply), readable by
// MeshLab, CloudCompare, Open3D and Blender.
//
// The file is
//   ply
//   format binary_little_endian 1.0
//   comment Reconduit point cloud
//   element vertex <N>
//   property float x          (double x, y, z with PlyOptions::double_precision)
//   property float y
//   property float z
//   property float nx         (only when normals are given)
//   property float ny
//   property float nz
//   property uchar red
//   property uchar green
//   property uchar blue
//   end_header
// followed by N records of those properties, packed without padding (15 bytes per vertex with
// float positions and no normals). Coordinates are written in the frame and units given (for
// our models: the reconstruction's world frame).
#ifndef RECONDUIT_CORE_IO_PLY_H_
#define RECONDUIT_CORE_IO_PLY_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

// A point cloud as a struct of arrays: colors.size() == positions.size(), and normals is
// either empty or of the same size.
struct PointCloud {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Matrix<std::uint8_t, 3, 1>> colors;  // RGB, 0-255.
  std::vector<Eigen::Vector3f> normals;                   // Unit vectors, or empty.
};

struct PlyOptions {
  // Positions as 64-bit doubles instead of 32-bit floats. Floats (7 significant digits: 0.1 mm
  // at 1 km) are enough for display and are what every viewer reads fastest.
  bool double_precision = false;
};

// The PLY header (text up to and including "end_header\n") for `num_points` vertices.
std::string PointCloudPlyHeader(std::size_t num_points,
                                bool has_normals,
                                const PlyOptions& options = PlyOptions());

// Writes `cloud` to `path`: streamed to a temporary file in the same folder, fsynced and
// renamed, so a reader never sees a partial file. InvalidArgument when the array sizes
// disagree; Internal on I/O failure.
Status WritePointCloudPly(const std::filesystem::path& path,
                          const PointCloud& cloud,
                          const PlyOptions& options = PlyOptions());

// The points of a reconstruction with their colours (increasing point id), for sparse.ply.
PointCloud PointCloudFromReconstruction(const Reconstruction& rec);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_PLY_H_
