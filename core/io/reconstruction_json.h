// Lossless JSON storage of a Reconstruction, for the pipeline's work folder: the sparse stage
// writes work/sparse/model_<k>.json and later stages, or a resumed job, read it back.
//
// Lossless means: reading gives a Reconstruction equal field by field to the one written —
// the same camera, image and point ids, every double bit for bit (numbers are written as the
// shortest decimal that reads back exactly), the same keypoints, observations in the same
// order, and point_for_keypoint rebuilt from the observations. Two documented exceptions:
// a non-finite point `error` is stored as null and reads back as +infinity, and a point with
// no observations cannot be stored (Reconstruction never keeps one). The next id that
// Reconstruction::AddPoint hands out after reading is the largest point id + 1.
//
// Layout (version 1), one line, no pretty-printing (about 100 bytes per observation):
//   {"format": "reconduit-reconstruction", "version": 1,
//    "cameras": [{"id", "width", "height", "focal", "cx", "cy", "k1", "k2"}],
//    "images":  [{"id", "camera_id", "name",
//                 "rotation": [qw, qx, qy, qz],   // cam_from_world, Hamilton, Eigen's order
//                 "translation": [tx, ty, tz],    // cam_from_world
//                 "keypoints": [x0, y0, x1, y1, ...]}],   // original-image pixels
//    "points":  [{"id", "xyz": [x, y, z], "rgb": [r, g, b], "error",
//                 "track": [image_id0, keypoint0, image_id1, keypoint1, ...]}]}
// Units and frames are those of core/scene/reconstruction.h: pixels of the original image with
// pixel centres at integer coordinates, poses world-to-camera, world units of the model.
#ifndef RECONDUIT_CORE_IO_RECONSTRUCTION_JSON_H_
#define RECONDUIT_CORE_IO_RECONSTRUCTION_JSON_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <filesystem>
#include <string>

namespace reconduit {

// The version this program writes and the only one it reads.
inline constexpr int kReconstructionJsonVersion = 1;

// Serialises `rec` to the one-line JSON text described above. InvalidArgument when `rec`
// breaks the Reconstruction invariants (model_io::CheckReconstruction: an observation that
// does not match point_for_keypoint, a non-finite pose or position, ...).
Result<std::string> ReconstructionToJson(const Reconstruction& rec);

// Parses the text written by ReconstructionToJson. InvalidArgument with the JSON path of the
// offending value (e.g. "images[3].keypoints: ...") for malformed input, an unknown format or
// an unsupported version.
Result<Reconstruction> ReconstructionFromJson(const std::string& text);

// Writes ReconstructionToJson(rec) to `path` atomically (core/io/file_util.h). The folder must
// exist.
Status WriteReconstructionJson(const std::filesystem::path& path, const Reconstruction& rec);

// Reads a file written by WriteReconstructionJson. NotFound when the file is missing;
// InvalidArgument, prefixed with the path, for a bad file.
Result<Reconstruction> ReadReconstructionJson(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_RECONSTRUCTION_JSON_H_
