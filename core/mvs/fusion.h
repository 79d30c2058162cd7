// Fusion of depth maps into one point cloud, and the per-pixel quality maps.
//
// A depth-map pixel is a 3-D point with a normal. It is *confirmed* by another view when that
// view's depth map, at the pixel where the point projects, holds a point that
//   - lies at the same depth within `max_relative_depth_error` (as seen from that view),
//   - projects back to within `max_reprojection_error_px` of the first pixel, and
//   - has a normal within `max_normal_angle_deg` of the first one.
// (The geometric consistency of COLMAP's fusion and of ARC3D's multi-view linking.)
//
// Quality maps (ARC3D): for every pixel of every depth map, the number of views that agree on
// its depth, itself included (0 where the map is empty). Users read them as "how trustworthy is
// the model here".
//
// Fusion: views are taken in order and their pixels row by row; a pixel not yet used that at
// least `min_views` views agree on (itself included) becomes one point, the mean of the
// agreeing points (position, normal and colour), seen by the agreeing views; every agreeing
// pixel is marked used, so a surface seen by several photos gives one point, not one per
// photo. Pixels fewer views agree on are dropped. The result is deterministic.
#ifndef RECONDUIT_CORE_MVS_FUSION_H_
#define RECONDUIT_CORE_MVS_FUSION_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/mvs/patch_match.h"
#include "core/util/cancel.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {

// One view's depth map with what fusion needs around it.
struct FusionView {
  const DepthMap* map = nullptr;  // Depth and normals in this view's camera frame.
  // CV_8UC3 BGR at the map's resolution, for the points' colours; empty: grey points.
  cv::Mat color;
  Camera camera;  // Pinhole (no distortion) at the map's resolution.
  Rigid3d cam_from_world;
  int image_id = -1;  // What the cloud's visibility lists.
  // Indices into the views given to FuseDepthMaps of the views to check this one against
  // (its dense-matching neighbours); empty: every other view.
  std::vector<int> neighbors;
};

struct FusionOptions {
  // Views that must agree on a point, the first included. [2, 32]
  int min_views = 2;
  // (0, 1)
  double max_relative_depth_error = 0.01;
  // (0, 100]
  double max_reprojection_error_px = 2.0;
  // (0, 180]
  double max_normal_angle_deg = 10.0;
  // Threads for the quality maps (core/util/parallel.h); the result does not depend on it.
  int num_threads = 0;

  // False, with a message naming the field, for values out of range.
  bool Check(std::string* error) const;
};

// The fused points, struct of arrays, in the world frame of the cameras.
struct DenseCloud {
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;  // Unit, pointing towards the cameras that see it.
  std::vector<Eigen::Matrix<std::uint8_t, 3, 1>> colors;  // RGB.
  // The image ids that see point i: visibility[visibility_offsets[i] ..
  // visibility_offsets[i + 1]), increasing. visibility_offsets has size() + 1 entries.
  std::vector<std::uint32_t> visibility_offsets{0};
  std::vector<int> visibility;

  std::size_t size() const { return positions.size(); }
};

struct FusionResult {
  DenseCloud cloud;
  // Per view, CV_8UC1: how many views agree with the pixel's depth, itself included (capped at
  // 255); 0 where the depth map is empty.
  std::vector<cv::Mat> quality;
  // Per view: of its depths that land, projected into a neighbour, on a pixel with a depth, the
  // share within 1 % of that depth (as seen from the neighbour). Counted over every pixel and
  // neighbour; NaN where no depth lands on another map. How well the maps agree, before any
  // normal or reprojection check.
  std::vector<double> neighbor_agreement;
};

// Throws CheckError for invalid options or views (null maps, sizes that do not match their
// camera, neighbour indices out of range) and CanceledError when `cancel` fires.
FusionResult FuseDepthMaps(const std::vector<FusionView>& views,
                           const FusionOptions& options,
                           const CancelToken& cancel = CancelToken());

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_FUSION_H_
