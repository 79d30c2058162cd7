// Depth and normal maps by PatchMatch stereo over several views, on the CPU.
//
// Method (Bleyer et al. 2011, "PatchMatch Stereo"; multi-view as in Galliani et al. 2015,
// "Gipuma", and Schönberger et al. 2016, "Pixelwise view selection", COLMAP): every pixel of
// the reference photo holds a plane hypothesis, a depth along its ray and a normal. A plane
// induces a homography into each source photo; the hypothesis's cost in a source is 1 - NCC
// of the reference window and the source window it maps to; its multi-view cost is the mean of
// the best `top_k` source costs (occlusions and non-overlap only hurt some sources). Every
// pixel starts from a random plane (or from a sparse point that projects into it), then each
// iteration (1) tries its neighbours' planes (propagation) and (2) small random changes of its
// own (refinement), keeping whatever lowers its cost.
//
// Parallel propagation: pixels are coloured like a checkerboard; all red pixels update at once
// reading only black ones, then the reverse (Gipuma). The result does not depend on the number
// of threads: each pixel's random numbers come from a hash of (seed, pixel, iteration).
//
// Coarse-to-fine (`pyramid_levels`): the photos are halved `pyramid_levels` times; the
// coarsest level runs the full search from random planes, and each finer level starts every
// pixel from the plane of the coarse pixel under it and only polishes: it propagates from the
// four neighbours 3 pixels away (not the adjacent ones) and refines by small perturbations
// only (no fresh random depth or normal). Speed (core/mvs/patch_match_benchmark.cc: 1536 x
// 1024 reference, 6 sources, floor and box, CPU seconds on this 2-core AMD EPYC, 2 threads):
//
//   single level, 5 sweeps (before)                 78.8-94.7 s  filled 99.96 %  0.1 %: 97.8 %
//   2 levels, 5 + 2 + 2 sweeps, all candidates (*)        38.5 s  filled 99.92 %  0.1 %: 98.3 %
//   2 levels, finer levels polishing (*)                  20.3 s  filled 99.77 %  0.1 %: 98.5 %
//   3 levels, polishing (*)                               20.0 s  filled 99.77 %  0.1 %: 98.6 %
//   2 levels, polishing, 1 sweep per finer level (*)      14.0 s  filled 99.50 %  0.1 %: 97.8 %
//   2 levels, polishing, 3 sweeps per finer level (*)     28.9 s  filled 99.80 %  0.1 %: 98.5 %
//   the default: 2 levels, polishing, pair gathers   14.1-18.8 s  (the same map as row 3)
//
// ("filled": true-surface pixels with a depth; "0.1 %": share of those within 0.1 % of the
// true depth; CPU times of repeated runs vary by up to 30 % with the shared machine's load; (*):
// with the first AVX2 kernel, one 32-bit gather per bilinear corner; see SourceCost in the .cc.)
// Starting from good planes also makes the maps more accurate than the single level's 5 sweeps,
// also on noisy photos (4 grey levels of Gaussian noise, 768 x 512: within 0.2 % 89.7 % -> 92.9 %
// of the filled pixels, filled 99.92 % -> 99.61 %). Wall time on a shared machine: 11.3-12.2 s on 2
// threads for 14.1-14.4 s of CPU at a load average of 2.3 from others (4 sources: 5.3 s wall, 9.8 s
// CPU); 21-80 s under heavier load.
//
// What stays empty (depth 0): pixels whose window has almost no texture (its grey levels'
// standard deviation below `min_texture_stddev`, or below `noise_texture_factor` times the
// photo's estimated noise: the sky, a plain wall, a black background),
// and pixels whose best cost stays above `max_cost` (nothing matched: occlusions, surfaces seen
// by no source). A depth map is never filled by guessing.
//
// Images are single-channel float, undistorted (pinhole cameras) and at the working resolution;
// see core/mvs/mvs_view.h for how photos are prepared.
#ifndef RECONDUIT_CORE_MVS_PATCH_MATCH_H_
#define RECONDUIT_CORE_MVS_PATCH_MATCH_H_

#include "core/mvs/mvs_view.h"
#include "core/util/cancel.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {

struct PatchMatchOptions {
  // The matching window is (2 radius + 1)^2 pixels, sampled every `window_step` pixels in x and
  // y: radius 4, step 2 compares 25 samples over a 9 x 9 window. [1, 15], [1, radius]
  int window_radius = 4;
  int window_step = 2;
  // Propagation + refinement sweeps (each a red and a black half-sweep) at the coarsest level
  // (see pyramid_levels). [1, 50]
  int num_iterations = 5;
  // Coarse-to-fine: the number of half-resolution levels below the working resolution (0: a
  // single level; fewer when the photos would get smaller than two windows across). The
  // coarsest level runs `num_iterations` sweeps from random planes; every finer level starts
  // from the planes of the level below and runs `upsampled_iterations` sweeps whose refinement
  // perturbations are those of iteration `upsampled_first_iteration` on (they halve each
  // iteration: 2 starts at +-1 % of the depth). 2 levels and 2 sweeps: see the table above (a
  // third level gains little at 1536 x 1024; one sweep loses 0.3 % of the pixels and 0.7 % of
  // the accuracy). First iteration 0, 1, 3, 4 at 768 x 512: 87.6, 87.9, 88.4, 88.4 % of the
  // pixels within 0.1 %, against 88.4 % for 2. [0, 4], [1, 50], [0, 50]
  int pyramid_levels = 2;
  int upsampled_iterations = 2;
  int upsampled_first_iteration = 2;
  // The multi-view cost averages the best `top_k` sources' costs (of those whose window lies
  // inside their image; see kMissingSourcePenalty in the .cc). [1, 16]
  int top_k = 2;
  // Pixels whose window's grey-level standard deviation is below this are left empty, in units
  // of the image's grey levels (images scaled to [0, 255]). Measured: noise of 2 grey levels on
  // a plain panel (tests/dense_synthetic_test.cc, 6 sources) gets chance matches on 1.1-2.0 %
  // of it at 1.0, 0.3-0.45 % at 1.5, none at 2.0 and 2.5, with the same completeness
  // elsewhere; but fountain-P11's maps at 1600 px (where halving has averaged the noise away)
  // lose low-contrast ground: 84-98 % of pixels filled at 1.0, 76-88 % at 2.5 (3.92 against
  // 3.45 M fused points). 1.5 kept the quick test's panels under the 1 %, but not the
  // long test's (480 x 360: 2.6 % and 1.5 %): see noise_texture_factor. >= 0
  double min_texture_stddev = 1.5;
  // ... and below this many times the reference's own noise (estimated per photo and pyramid
  // level, core/mvs/image_noise.h), when that is higher. Pure noise of standard deviation s
  // gives windows of about s (25 samples: within +-15 %), so 1.5 leaves them empty while
  // texture of 1.1 s and more still matches. tests/dense_synthetic_test's plain panels (noise of
  // 2 grey levels) went from 0.3-0.45 % (320 x 240) and 2.6 % / 1.5 % (480 x 360) covered to
  // none, completeness elsewhere within 0.3 points; patch_match_test's noisy square from 760
  // chance pixels to none. 0: the fixed threshold only. >= 0
  double noise_texture_factor = 1.5;
  // Pixels whose final cost is above this (1 - NCC) are left empty. (0, 2]
  double max_cost = 0.6;
  // Normals more than this many degrees away from facing the camera are not tried. (0, 90)
  double max_normal_angle_deg = 80.0;
  // True: the window cost uses AVX2 when the CPU has it (chosen at run time); false: the
  // portable kernel everywhere. The two agree to float rounding (the maps may differ in a few
  // pixels); each is deterministic.
  bool use_simd = true;
  // Threads (core/util/parallel.h); the result does not depend on it.
  int num_threads = 0;
  std::uint64_t seed = 0;

  // False, with a message naming the field, for values out of range.
  bool Check(std::string* error) const;
};

// A reference photo's depth in the camera frame (z, not distance along the ray).
struct DepthMap {
  cv::Mat depth;   // CV_32FC1, 0 where empty.
  cv::Mat normal;  // CV_32FC3, unit normals in the camera frame, facing the camera (n.z < 0).
  cv::Mat cost;    // CV_32FC1, the multi-view cost (1 - NCC, [0, 2]); 2 where empty.
  // The reference's noise as estimated at the working resolution (grey levels; 0 when
  // PatchMatchOptions::noise_texture_factor is 0).
  double noise_stddev = 0.0;
};

// A known depth to start from: a sparse point that projects to `pixel` of the reference.
struct DepthSeed {
  Eigen::Vector2d pixel;
  double depth = 0.0;
};

struct PatchMatchInput {
  const MvsView* reference = nullptr;
  std::vector<const MvsView*> sources;
  // Depths are searched in [min_depth, max_depth] (uniform in inverse depth). 0 < min < max.
  double min_depth = 0.0;
  double max_depth = 0.0;
  // Sparse points seen by the reference; each starts the pixel it falls in (optional).
  std::vector<DepthSeed> seeds;
};

// Runs PatchMatch for `input.reference`. Throws CheckError for invalid options or input
// (no source, mismatched image sizes, distorted cameras, bad depth range) and CanceledError
// when `cancel` fires (checked between half-sweeps). Thread-safe for distinct outputs.
DepthMap ComputeDepthMap(const PatchMatchInput& input,
                         const PatchMatchOptions& options,
                         const CancelToken& cancel = CancelToken());

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_PATCH_MATCH_H_
