// How much sensor noise a photo carries, so that dense matching can tell texture from noise.
//
// A window whose grey levels vary by no more than the photo's noise holds nothing to match:
// PatchMatch leaves such pixels empty (PatchMatchOptions::noise_texture_factor). A fixed
// threshold cannot serve every photo: 2 grey levels of noise on a plain panel passed a
// threshold of 1.5 grey levels and got chance depths on 2.6 % of it, while fountain-P11's
// low-contrast ground, nearly noise-free after the working size's averaging, needs about
// that threshold to be filled (see PatchMatchOptions::min_texture_stddev).
//
// The estimator is Immerkær's ("Fast Noise Variance Estimation", CVIU 1996): the photo filtered
// with the difference of two Laplacians, [1 -2 1; -2 4 -2; 1 -2 1], which cancels grey levels
// that are constant, linear or quadratic over 3 x 3 pixels and leaves white noise of standard
// deviation s with a mean absolute response of 6 s sqrt(2 / pi). Immerkær averages over the
// whole photo, which counts fine texture as noise; here the average is taken per block of
// `block_size` pixels and the estimate is that of the flattest blocks (the `percentile` of the
// blocks' means), where only noise is left; for pure noise that is a few per cent low (the
// blocks' means scatter; image_noise_test). Blocks with a clipped pixel (0 or 255: a black
// background, a burnt-out sky) or no response at all (a rendered flat colour) say nothing
// about the sensor and are skipped, so grey levels must be on the 0-255 scale.
// Noise that the photo's resampling has correlated between neighbouring pixels is
// underestimated (the filter sees high frequencies only): the threshold derived from it errs
// towards keeping pixels.
#ifndef RECONDUIT_CORE_MVS_IMAGE_NOISE_H_
#define RECONDUIT_CORE_MVS_IMAGE_NOISE_H_

#include <opencv2/core.hpp>

namespace reconduit {

struct NoiseEstimateOptions {
  int block_size = 32;      // Pixels per block side. >= 4
  double percentile = 0.1;  // Of the blocks' mean responses, flattest first. [0, 1]
};

// The standard deviation of white noise in `gray` (CV_32FC1 or CV_8UC1), in its grey levels;
// 0 when the image is smaller than one block or has no block with any response.
double EstimateNoiseStddev(const cv::Mat& gray, const NoiseEstimateOptions& options = {});

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_IMAGE_NOISE_H_
