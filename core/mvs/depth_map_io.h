// Depth maps on disk: the exact form the dense stage resumes from, and the 16-bit PNG + JSON
// that users download (depth/<name>.png and depth/<name>.json; schema/README.md documents both).
//
// Download form. A 16-bit grey PNG of the working size: 0 where there is no depth, otherwise
//   depth = depth_min + (value - 1) / 65534 * (depth_max - depth_min)
// with depth_min and depth_max the smallest and largest depth of the map (z in the camera
// frame, the reconstruction's units) in the JSON beside it, which also holds the working
// camera (pinhole, no distortion: the PNG's pixels are the undistorted, scaled photo's) and the
// pose, so the map can be turned back into points without anything else. The step is
// (depth_max - depth_min) / 65534: 0.2 mm over a 4-15 m scene.
//
// Work form (resume). Depth, normal and cost as raw float32 rows behind a small header
// ("RCDM", version, width, height), written atomically: a finished map is bit-exact after a
// resume.
#ifndef RECONDUIT_CORE_MVS_DEPTH_MAP_IO_H_
#define RECONDUIT_CORE_MVS_DEPTH_MAP_IO_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/mvs/patch_match.h"
#include "core/util/status.h"

#include <filesystem>

namespace reconduit {

// Writes `map` in the work form; Internal on I/O failure.
Status WriteDepthMapBinary(const std::filesystem::path& path, const DepthMap& map);
// Reads the work form; NotFound, or InvalidArgument for a file that is not a whole depth map.
Result<DepthMap> ReadDepthMapBinary(const std::filesystem::path& path);

// Writes `png_path` (16-bit PNG) and `json_path` (range, camera, pose) as described above.
// InvalidArgument when the depth is not CV_32FC1 of the camera's size; Internal on I/O failure.
Status WriteDepthPng(const std::filesystem::path& png_path,
                     const std::filesystem::path& json_path,
                     const cv::Mat& depth,
                     const Camera& camera,
                     const Rigid3d& cam_from_world);
// Reads a depth PNG back to metres (CV_32FC1, 0 where empty) using its JSON.
Result<cv::Mat> ReadDepthPng(const std::filesystem::path& png_path,
                             const std::filesystem::path& json_path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_DEPTH_MAP_IO_H_
