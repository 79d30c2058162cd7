// COLMAP's text model (cameras.txt, images.txt, points3D.txt), as specified in COLMAP's
// "Output Format" documentation (https://colmap.github.io/format.html#text-format).
//
// cameras.txt   CAMERA_ID RADIAL WIDTH HEIGHT f cx cy k1 k2          (one line per camera)
// images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME         (two lines per image)
//               X Y POINT3D_ID X Y POINT3D_ID ...                    (every keypoint; -1: none)
// points3D.txt  POINT3D_ID X Y Z R G B ERROR IMAGE_ID POINT2D_IDX ...  (one line per point)
// Lines starting with '#' are comments; each file starts with COLMAP's usual comment header.
//
// Mapping to Reconstruction:
// - Ids. COLMAP's ids start at 1, ours at 0: every CAMERA_ID, IMAGE_ID and POINT3D_ID written
//   is our id + 1, and the reader subtracts 1 (so reading COLMAP's own output gives ids from
//   0). POINT2D_IDX is the keypoint index in both (0-based); POINT3D_ID -1 means no point.
// - Camera model. Ours is COLMAP's RADIAL model (f, cx, cy, k1, k2 with distortion on
//   normalised coordinates). The writer always uses RADIAL; the reader also accepts
//   SIMPLE_PINHOLE (f, cx, cy), SIMPLE_RADIAL (f, cx, cy, k) and PINHOLE with fx == fy, and
//   refuses other models.
// - Pixels. COLMAP puts the centre of the top-left pixel at (0.5, 0.5), we put it at (0, 0)
//   (core/geometry/camera.h): the writer adds 0.5 to principal points and keypoints, the reader
//   subtracts 0.5.
// - Poses are cam_from_world in both (Hamilton quaternion QW QX QY QZ, x_cam = R x_world + t).
//   The reader normalises the quaternion.
// - NAME is RegisteredImage::name as is. Names may not contain line breaks (the writer refuses
//   them). COLMAP itself cuts a name at its first space; our reader takes the rest of the line,
//   so names with spaces round-trip here but not through COLMAP.
// Numbers are written as the shortest decimal that reads back exactly (no precision is lost).
#ifndef RECONDUIT_CORE_IO_COLMAP_TEXT_H_
#define RECONDUIT_CORE_IO_COLMAP_TEXT_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <filesystem>

namespace reconduit {

// Writes cameras.txt, images.txt and points3D.txt into `folder` (created if missing), each
// atomically. InvalidArgument when `rec` breaks the Reconstruction invariants or an image name
// contains a line break; Internal on I/O failure.
Status WriteColmapText(const std::filesystem::path& folder, const Reconstruction& rec);

// Reads the three files from `folder` (written by WriteColmapText or by COLMAP's
// model_converter --output_type TXT). NotFound when a file is missing; InvalidArgument with
// "file:line: problem" for a malformed line, an unsupported camera model, an unknown
// reference, or a POINT3D_ID in images.txt that disagrees with the tracks in points3D.txt.
Result<Reconstruction> ReadColmapText(const std::filesystem::path& folder);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IO_COLMAP_TEXT_H_
