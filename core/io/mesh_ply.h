// Triangle meshes as binary little-endian PLY (work/mesh/mesh.ply; MeshLab, Blender,
// CloudCompare and Open3D open it):
//   element vertex <N>
//   property float x, y, z             position, in the reconstruction's world frame
//   property float nx, ny, nz          unit normal (only when the mesh has normals)
//   property uchar red, green, blue    (only when the mesh has colours)
//   element face <F>
//   property list uchar int vertex_indices
//                                      counter-clockwise seen from outside
// Texture coordinates are not written: the textured model is model.glb.
#ifndef RECONDUIT_CORE_IO_MESH_PLY_H_
#define RECONDUIT_CORE_IO_MESH_PLY_H_

#include "core/scene/triangle_mesh.h"
#include "core/util/status.h"

#include <filesystem>

namespace reconduit {

// Writes atomically. InvalidArgument when normals or colours are neither empty nor one per
// vertex, or a face's index is out of range; Internal on I/O failure.
Status WriteMeshPly(const std::filesystem::path& path, const TriangleMesh& mesh);

// Reads a file written by WriteMeshPly (other layouts: InvalidArgument naming what differs;
// truncated files and out-of-range indices: InvalidArgument); NotFound when missing.
Result<TriangleMesh> ReadMeshPly(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_MESH_PLY_H_
