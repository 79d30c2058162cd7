// Helpers shared by the readers and writers of sparse models (reconstruction_json, colmap_text,
// bundler, cameras_json): exact number formatting and parsing, whitespace tokenising, and
// rebuilding a Reconstruction with given point ids. Not part of the public export API.
#ifndef RECONDUIT_CORE_IO_MODEL_IO_UTIL_H_
#define RECONDUIT_CORE_IO_MODEL_IO_UTIL_H_

#include "core/scene/reconstruction.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <string>
#include <string_view>
#include <vector>

namespace reconduit::model_io {

// Appends the shortest decimal text that reads back as exactly `value` (std::to_chars;
// locale-independent; "inf", "-inf", "nan" for non-finite values).
void AppendDouble(double value, std::string* out);
// Appends `value` in decimal.
void AppendInt(long long value, std::string* out);

// Parses the whole token as a double / an int (locale-independent). False on any trailing
// character, overflow or empty input.
bool ParseDouble(std::string_view token, double* value);
bool ParseInt(std::string_view token, int* value);

// Splits at runs of spaces, tabs and carriage returns; no empty tokens.
std::vector<std::string_view> SplitWhitespace(std::string_view line);

// True when every coefficient is finite.
template <typename Derived>
bool AllFinite(const Eigen::MatrixBase<Derived>& m) {
  return m.allFinite();
}

// Checks the invariants the exporters rely on: every image's camera exists, every observation
// names a registered image and a keypoint in range whose point_for_keypoint is the point, no
// keypoint points at a point that does not list it, and poses, intrinsics, keypoints and point
// positions are finite. InvalidArgument naming the first offending item otherwise.
Status CheckReconstruction(const Reconstruction& rec);

// Adds points to a Reconstruction under chosen ids. Reconstruction::AddPoint numbers points
// consecutively and keeps its counter private, so ids are reproduced by adding (and deleting)
// placeholder points for the gaps: ids must come in increasing order and the cost is linear in
// the largest id. Afterwards the Reconstruction's next AddPoint returns the largest id + 1.
class PointIdRestorer {
 public:
  // `rec` must not have had any point added yet; not owned, must outlive this object.
  explicit PointIdRestorer(Reconstruction* rec) : rec_(rec) {}

  // Adds the point with id `id` (> every id added before) observed by `observations`.
  // InvalidArgument, with `where` as prefix, when an observation names an unregistered image,
  // a keypoint out of range or one that already observes a point.
  Status Add(int id,
             const Eigen::Vector3d& xyz,
             const std::vector<Observation>& observations,
             std::string_view where);

 private:
  Reconstruction* rec_;
  int next_id_ = 0;
};

}  // namespace reconduit::model_io

#endif  // RECONDUIT_CORE_IO_MODEL_IO_UTIL_H_
