// cameras.json: every camera of the result in one small, self-describing JSON file, for users
// who want the calibration without parsing COLMAP or Bundler files. The schema is
// schema/json/cameras.schema.json (JSON Schema draft 2020-12); schema/README.md explains it.
//
//   {"version": 1,
//    "coordinate_frame": "<the conventions below, in words>",
//    "images": [{"name": "IMG_0001.JPG", "width": 4000, "height": 3000,
//                "focal": 3210.5, "principal_point": [1999.5, 1499.5], "k1": -0.05, "k2": 0.01,
//                "rotation": [[r00, r01, r02], [r10, r11, r12], [r20, r21, r22]],
//                "center": [x, y, z], "registered": true}],
//    "unregistered": ["IMG_0007.JPG"]}
//
// Conventions:
// - "rotation" is the world-to-camera rotation R (rows listed in order) and "center" the
//   camera centre c in world coordinates: x_cam = R (X - c), i.e. t = -R c and c = -Rᵀ t for
//   our cam_from_world (R, t).
// - The camera looks down +z, x right, y down. Projection: (x, y) = (x_cam / z_cam, y_cam /
//   z_cam), r² = x² + y², s = 1 + k1 r² + k2 r⁴, pixel = (focal s x + cx, focal s y + cy).
// - Pixels are those of the ORIGINAL uploaded image (width x height from the camera), with
//   the centre of the top-left pixel at (0, 0): the image centre is ((width - 1) / 2,
//   (height - 1) / 2). Add 0.5 to principal points for conventions that put pixel centres at
//   half-integers (COLMAP, OpenGL texture coordinates times the size).
// - World frame and units are the reconstruction's (metric up to one global scale).
// Images are listed in increasing image id; "unregistered" keeps the order given.
#ifndef RECONDUIT_CORE_IO_CAMERAS_JSON_H_
#define RECONDUIT_CORE_IO_CAMERAS_JSON_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

// The version this program writes.
inline constexpr int kCamerasJsonVersion = 1;

// The text of cameras.json (indented, ends with a newline). `unregistered_names` are the
// photos that are not in `rec` (accepted but not registered). InvalidArgument when `rec`
// breaks the Reconstruction invariants (model_io::CheckReconstruction).
Result<std::string> CamerasJson(const Reconstruction& rec,
                                const std::vector<std::string>& unregistered_names);

// Writes CamerasJson(rec, unregistered_names) to `path` atomically.
Status WriteCamerasJson(const std::filesystem::path& path,
                        const Reconstruction& rec,
                        const std::vector<std::string>& unregistered_names);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_CAMERAS_JSON_H_
