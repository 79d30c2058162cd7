// dense.ply: the fused cloud with the photos that see each point.
//
// A binary little-endian PLY that every viewer opens (MeshLab, CloudCompare, Blender, Open3D
// read the standard properties and skip the list they do not know):
//   element vertex <N>
//   property float x, y, z          position, in the reconstruction's world frame
//   property float nx, ny, nz       unit normal, towards the cameras that see the point
//   property uchar red, green, blue
//   property list uchar int visibility
//                                   the photos that see the point, increasing: as the
//                                   dense stage writes it, positions in cameras.json's
//                                   "images" list (from 0)
// The mesh and texture stages read the visibility back (ReadDenseCloudPly); COLMAP keeps the
// same lists in a separate fused.ply.vis, which is one more file to lose.
#ifndef RECONDUIT_CORE_MVS_DENSE_CLOUD_IO_H_
#define RECONDUIT_CORE_MVS_DENSE_CLOUD_IO_H_

#include "core/mvs/fusion.h"
#include "core/util/status.h"

#include <filesystem>

namespace reconduit {

// Writes `cloud` atomically (a reader never sees a partial file). InvalidArgument when its
// arrays disagree or a point is seen by more than 255 photos; Internal on I/O failure.
Status WriteDenseCloudPly(const std::filesystem::path& path, const DenseCloud& cloud);

// Reads a file written by WriteDenseCloudPly (other PLY layouts are refused with
// InvalidArgument naming what differs); NotFound when missing.
Result<DenseCloud> ReadDenseCloudPly(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_DENSE_CLOUD_IO_H_
