// A triangle mesh, optionally textured: what the mesh and texture stages hand to the writers.
//
// Plain data, like Reconstruction beside it, so that core/io writes meshes (PLY, glTF) without
// depending on the algorithms that make them (core/mesh, core/texture).
//
// Frames and units: positions are in the reconstruction's world frame and units (those of
// cameras.json). Faces are counter-clockwise seen from outside: the face normal
// (b - a) x (c - a) points away from the surface, towards the cameras that saw it.
// Texture coordinates follow glTF's convention: (0, 0) is the top-left corner of the page
// image, u to the right, v down, both in [0, 1].
#ifndef RECONDUIT_CORE_SCENE_TRIANGLE_MESH_H_
#define RECONDUIT_CORE_SCENE_TRIANGLE_MESH_H_

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace reconduit {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions;
  // Per vertex, unit; empty when not computed.
  std::vector<Eigen::Vector3f> normals;
  // Per vertex, RGB; empty when the mesh has no vertex colours.
  std::vector<Eigen::Matrix<std::uint8_t, 3, 1>> colors;
  // Vertex indices, counter-clockwise seen from outside.
  std::vector<Eigen::Vector3i> faces;

  // Texture (set by the texture stage; all empty for an untextured mesh).
  // 3 per face, in the order of the face's corners: texcoords[3 * f + k] for corner k of f.
  std::vector<Eigen::Vector2f> texcoords;
  // Per face, the index into texture_pages of the page its texcoords refer to.
  std::vector<int> face_pages;
  // CV_8UC3 BGR atlas pages (OpenCV's channel order; writers convert).
  std::vector<cv::Mat> texture_pages;

  std::size_t NumVertices() const { return positions.size(); }
  std::size_t NumFaces() const { return faces.size(); }
  bool HasTexture() const { return !texture_pages.empty(); }
};

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_TRIANGLE_MESH_H_
