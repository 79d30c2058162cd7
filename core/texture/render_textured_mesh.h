// Renders a textured TriangleMesh from a camera: what the model looks like from a photo's
// viewpoint, for held-out-photo comparisons (issue 11) and tests.
//
// A z-buffer rasterizer: pixel centres at integer coordinates, perspective-correct texture
// coordinates, bilinear texture lookup (clamped at the page's edges), no lighting (the texture
// is the photos' colour). Faces with a vertex behind the near plane (z <= near) are skipped,
// which only matters for meshes reaching behind the camera. A camera with distortion is
// rendered as its distortion-free pinhole at the same size and then warped through the
// distortion model, so pixels whose undistorted position falls outside the pinhole image stay
// uncovered (the corners of a strongly barrel-distorted view). An untextured mesh is drawn with
// its vertex colours (interpolated), or grey without them.
#ifndef RECONDUIT_CORE_TEXTURE_RENDER_TEXTURED_MESH_H_
#define RECONDUIT_CORE_TEXTURE_RENDER_TEXTURED_MESH_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/triangle_mesh.h"

#include <opencv2/core.hpp>

namespace reconduit {

struct MeshRenderOptions {
  // Faces seen from behind (their CCW-from-outside normal pointing away from the camera) are
  // not drawn: the inside of a surface is not what a photo shows.
  bool cull_back_faces = true;
  // Near plane, in the units of the mesh, > 0.
  double near = 1e-6;
  // BGR colour of uncovered pixels.
  cv::Scalar background = cv::Scalar(0, 0, 0);
};

struct MeshRender {
  cv::Mat image;     // camera.height x camera.width, CV_8UC3 BGR.
  cv::Mat coverage;  // camera.height x camera.width, CV_8UC1: 255 where a face is drawn, else 0.
  cv::Mat depth;     // camera.height x camera.width, CV_32FC1: camera z, 0 where uncovered.
};

// Throws CheckError for an invalid camera or a mesh whose texture fields are inconsistent.
// Thread-safe; deterministic.
MeshRender RenderTexturedMesh(const TriangleMesh& mesh,
                              const Camera& camera,
                              const Rigid3d& cam_from_world,
                              const MeshRenderOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_TEXTURE_RENDER_TEXTURED_MESH_H_
