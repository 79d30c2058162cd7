// model.glb: the textured mesh and the photos' cameras as one binary glTF 2.0 file.
//
// What the file holds (schema/README.md documents the same for users):
// - One scene, right-handed, y up, in the reconstruction's units (those of cameras.json:
//   metric up to one unknown scale). "Up" is the average up direction of the photos: the
//   camera's -y axis (image up) in the world, averaged over the cameras, since people hold
//   cameras upright. The average viewing direction, made horizontal, becomes glTF's -Z, so a
//   viewer's default camera (looking down -Z) sees the side the photos saw. With
//   GltfOptions::center the model is also translated so that the centre of the mesh's bounding
//   box is the origin. The whole transform is recorded in the scene's extras:
//     scenes[0].extras.gltf_from_world = {"rotation": [9 numbers, row-major],
//                                         "translation": [3 numbers]}
//   with p_gltf = rotation * p_world + translation, so the coordinates of cameras.json are
//   p_world = rotation^T * (p_gltf - translation).
// - The mesh, node "mesh", positions already in the glTF frame (no node transform):
//   untextured: one primitive with POSITION, NORMAL (when the mesh has normals) and COLOR_0
//   (unsigned byte normalised RGBA, alpha 255, when it has colours; the material is then
//   KHR_materials_unlit, since photo colours already hold the shading; a mesh with neither
//   texture nor colours gets a plain lit grey material);
//   textured: one primitive per atlas page that has faces, vertices split where a vertex has
//   several texture coordinates (identical (vertex, uv) pairs share one vertex), POSITION,
//   NORMAL (when present), TEXCOORD_0, and a material with the page as baseColorTexture,
//   KHR_materials_unlit, and metallicFactor 0 / roughnessFactor 1 for viewers without the
//   extension. Pages are JPEG (OpenCV's imgcodecs, GltfOptions::jpeg_quality) stored in the
//   GLB's binary chunk (bufferView images, image/jpeg), sampled with clamp-to-edge.
//   Indices are unsigned short up to 65535 vertices per primitive, unsigned int above.
// - One node per photo, named after the photo as uploaded (extension included, "0000.jpg"),
//   carrying a perspective camera of the same name. glTF cameras look down their local -Z
//   with +Y up, so the node's rotation is gltf_from_world * world_from_cam * diag(1, -1, -1)
//   and its translation the camera centre in the glTF frame. yfov = 2 atan(height / 2 focal),
//   aspectRatio = width / height (glTF cannot express an off-centre principal point or
//   distortion); znear and zfar come from the extent of the mesh and the cameras. The camera's
//   extras hold the full intrinsics of core/geometry/camera.h: focal, cx, cy, width, height, k1,
//   k2 (pixels of the uploaded photo; the centre of the top-left pixel is (0, 0)).
//
// JPEG encoding lives here (reconduit_io links opencv_imgcodecs privately) because the mesh
// type holds its pages as cv::Mat; the server links reconduit_io but never this file's code.
// The file is assembled by hand (nlohmann::json for the small JSON chunk, the binary chunk
// written once) rather than through tinygltf's Model, which would hold a second and third
// copy of every buffer; tinygltf reads the files back in the tests.
#ifndef RECONDUIT_CORE_IO_GLTF_H_
#define RECONDUIT_CORE_IO_GLTF_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/triangle_mesh.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

// A photo's camera, for a camera node.
struct GltfCameraView {
  std::string name;  // The photo's name as uploaded, extension included ("0000.jpg").
  Camera camera;
  Rigid3d cam_from_world;
};

struct GltfOptions {
  // JPEG quality of the texture pages, 1-100.
  int jpeg_quality = 90;
  // Translate the model so that its bounding box is centred on the origin (recorded in the
  // scene's extras). Off: only the rotation.
  bool center = true;
};

// The frame model.glb is written in.
struct GltfFrame {
  Rigid3d gltf_from_world;
  Eigen::Vector3d up_in_world = Eigen::Vector3d(0, -1, 0);  // Unit; maps to glTF +Y.
};

struct GltfSummary {
  std::size_t num_vertices = 0;  // Written, after splitting per page and texture coordinate.
  std::size_t num_faces = 0;
  std::size_t num_primitives = 0;
  std::size_t num_images = 0;
  std::size_t num_cameras = 0;
  std::size_t file_bytes = 0;
  GltfFrame frame;
};

// The glTF frame of a mesh and its cameras: up is the normalised mean of the cameras' up
// directions (-y of each camera in the world); without cameras, or when they cancel out, the
// world's -y (the first camera's frame is the world frame of our reconstructions). The mean
// viewing direction, made perpendicular to up, maps to -Z (any perpendicular when it is
// degenerate). With options.center, the translation puts the centre of the mesh's bounding box
// (the cameras' when the mesh has no vertices) at the origin.
GltfFrame ComputeGltfFrame(const TriangleMesh& mesh,
                           const std::vector<GltfCameraView>& cameras,
                           const GltfOptions& options = GltfOptions());

// Writes model.glb atomically (temporary file in the same folder, fsync, rename).
// InvalidArgument, saying what is wrong, for a mesh without faces, a face index out of range,
// normals or colours whose count is not the vertex count, non-finite positions, texture
// arrays of the wrong size (texcoords != 3 per face, face_pages != 1 per face, a page index out
// of range, a page that is not a non-empty CV_8UC3 image), a camera that fails Camera::Check or
// has an empty or repeated name, or a JPEG quality outside 1-100; Internal on I/O or encoding
// failure. `summary` may be null.
Status WriteModelGlb(const std::filesystem::path& path,
                     const TriangleMesh& mesh,
                     const std::vector<GltfCameraView>& cameras,
                     const GltfOptions& options,
                     GltfSummary* summary);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_GLTF_H_
