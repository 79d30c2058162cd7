// Ground-truth cameras of benchmark photo sets.
//
// Two formats are read (see ../shared/datasets/README.md):
//  - Strecha: a folder of "<image name>.camera" files, 9 lines each: K (3 lines), distortion,
//    R camera-to-world (3 lines), the camera centre C, "width height"; P = K [Rᵀ | -Rᵀ C].
//  - Middlebury: "<name>_par.txt": N, then per view "name k11..k33 r11..r33 t1 t2 t3" with R
//    world-to-camera and P = K [R | t].
// Both become a name, K and a cam_from_world pose; K keeps fx and fy apart (the Middlebury
// temple's differ by 0.4 %).
#ifndef RECONDUIT_CORE_EVAL_GROUND_TRUTH_H_
#define RECONDUIT_CORE_EVAL_GROUND_TRUTH_H_

#include "core/geometry/rigid3.h"
#include "core/util/status.h"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {

struct GroundTruthCamera {
  std::string name;  // Image file name.
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Rigid3d cam_from_world;
  int width = 0;  // 0 when the format does not say.
  int height = 0;
};

Result<std::vector<GroundTruthCamera>> ReadStrechaCameras(const std::filesystem::path& folder);
Result<std::vector<GroundTruthCamera>> ReadMiddleburyPar(const std::filesystem::path& file);
// The Middlebury text of `cameras` (names without white space), at full double precision:
// ReadMiddleburyPar reads back the same names, K and poses. Synthetic sets carry their exact
// cameras in it (`reconduit synthetic`).
std::string FormatMiddleburyPar(const std::vector<GroundTruthCamera>& cameras);
// A folder is read as Strecha, a file as Middlebury.
Result<std::vector<GroundTruthCamera>> ReadGroundTruth(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_EVAL_GROUND_TRUTH_H_
