// Self-calibration of the focal length from fundamental matrices.
//
// With square pixels, zero skew and the principal point p known (the image centre), the only
// unknown of K = [f 0 px; 0 f py; 0 0 1] is f. For the right f, E = Kᵀ F K is an essential
// matrix, whose two non-zero singular values are equal (Mendonça & Cipolla 1999, "A simple
// technique for self-calibration"). Each pair of photos from one camera therefore gives a
// 1-D cost c(f) = (σ1 − σ2) / (σ1 + σ2), which we minimise by a log-spaced scan followed by
// golden-section refinement.
//
// A single pair is fragile: noise, and near-degenerate geometry (optical axes that meet, as
// when photos are taken around an object, make c flat), can move its minimum far away. Like
// ARC3D's statistical approach (Vergauwen, "Harnessing Structure-and-Motion", §3.9), we
// collect one estimate per pair, drop pairs whose minimum is not sharp, find the mode of the
// remaining estimates in log f (a kernel density vote), and then minimise the summed cost of
// the pairs that agree with the mode. Bundle adjustment refines the result.
#ifndef RECONDUIT_CORE_SFM_SELF_CALIBRATION_H_
#define RECONDUIT_CORE_SFM_SELF_CALIBRATION_H_

#include "core/util/status.h"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace reconduit {

struct FocalSearchRange {
  double min_focal = 0.0;  // Pixels, > 0.
  double max_focal = 0.0;  // Pixels, > min_focal.
};

// The focal search range for an image: [0.3, 8] x the longer side covers fisheyes-excluded
// phone wide angles (~0.6) to long lenses (~6).
FocalSearchRange DefaultFocalRange(int width, int height);

// The Mendonça–Cipolla cost of `focal` for a fundamental matrix between two photos that share
// K (principal point (cx, cy) in pixels, F in pixels: x2ᵀ F x1 = 0). In [0, 1]; 0 is a perfect
// essential matrix.
double EssentialCost(const Eigen::Matrix3d& fundamental, double focal, double cx, double cy);

struct PairFocalEstimate {
  double focal = 0.0;  // Pixels.
  double cost = 1.0;   // EssentialCost at the minimum.
  // How much the cost rises 30 % away from the minimum (the smaller of the two sides): a flat
  // valley (degenerate pair) has sharpness near 0.
  double sharpness = 0.0;
};

// The best focal for one pair within `range`; nullopt when the minimum is on the range
// boundary (no interior minimum: the pair says nothing about f).
std::optional<PairFocalEstimate> EstimateFocalFromFundamental(const Eigen::Matrix3d& fundamental,
                                                              double cx,
                                                              double cy,
                                                              const FocalSearchRange& range);

struct SharedFocalOptions {
  // Pairs whose minimum is less sharp than this are not used. [0, 1]
  double min_sharpness = 0.02;
  // Pairs whose minimum cost exceeds this are not used (F far from an essential matrix). [0, 1]
  double max_cost = 0.25;
  // Estimates within this relative distance of the mode count as agreeing. (0, 1]
  double agreement = 0.1;
  // At least this many pairs must agree with the mode. [1, ...]
  int min_agreeing_pairs = 2;

  bool Check(std::string* error) const;
};

struct SharedFocalEstimate {
  double focal = 0.0;    // Pixels.
  int num_pairs = 0;     // Fundamental matrices given.
  int num_usable = 0;    // Pairs with a sharp interior minimum.
  int num_agreeing = 0;  // Usable pairs within `agreement` of the result.
  // Median absolute relative deviation of the agreeing pairs' estimates from the result.
  double spread = 0.0;
};

// One focal length shared by every photo of the pairs. Degenerate (with a message) when too
// few pairs give a usable, agreeing estimate.
Result<SharedFocalEstimate> EstimateSharedFocal(const std::vector<Eigen::Matrix3d>& fundamentals,
                                                double cx,
                                                double cy,
                                                const FocalSearchRange& range,
                                                const SharedFocalOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SFM_SELF_CALIBRATION_H_
