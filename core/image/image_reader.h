// Reading one photo: validation with per-file reasons, EXIF, decoding and orientation.
//
// InspectImage checks a file the way ingest needs: every check of InspectImageHeader
// (image_check.h: format by content, size limits from the header, truncation, EXIF), then a
// full decode to prove the pixels decode (a photo corrupt in the middle of its compressed data
// is refused here, not by the header checks), then it drops the pixels. ReadImage runs the
// same checks and returns the pixels for later stages.
//
// Orientation: pixels are decoded as stored and rotated/flipped here by the EXIF orientation
// tag (read with exiv2 for all three formats), so the sizes, the focal prior and the pixels
// always agree: width and height are as displayed.
//
// Failures are values: a non-OK Status whose message names the file, e.g.
//   "IMG_1.jpg: truncated: the JPEG data ends before its end-of-image marker".
// Codes: NotFound (cannot open), ResourceExhausted (over a size limit), InvalidArgument
// (everything else that is wrong with the file).
//
// Thread-safety: all functions may be called concurrently on different files.
#ifndef RECONDUIT_CORE_IMAGE_IMAGE_READER_H_
#define RECONDUIT_CORE_IMAGE_IMAGE_READER_H_

#include "core/image/image_check.h"
#include "core/util/status.h"

#include <opencv2/core.hpp>

#include <filesystem>

namespace reconduit {

// Validates and describes one file, decoding it once to prove it decodes. Never throws for a
// bad file; throws CheckError when the options are invalid.
ImageRecord InspectImage(const std::filesystem::path& path, const ImageReaderOptions& options);

// Reads one photo as 8-bit, 3-channel BGR (grey and 16-bit images are converted, alpha is
// dropped), oriented by its EXIF tag and downscaled to options.max_side when set. Refuses the
// same files as InspectImage, with the same reasons. Throws CheckError on invalid options.
// A JPEG at least twice the working size in both directions is decoded at 1/2, 1/4 or 1/8
// scale (libjpeg's scale-on-decode), then resized: the full-size pixels never exist in
// memory. Other formats are decoded at full size, then resized.
// When `info` is non-null it receives the photo's description (width and height as
// displayed, before downscaling).
Result<cv::Mat> ReadImage(const std::filesystem::path& path,
                          const ImageReaderOptions& options,
                          ImageInfo* info = nullptr);

// Returns `image` rotated/flipped so that a stored image with EXIF orientation `orientation`
// (1..8) appears upright. Orientations 5..8 swap width and height. Out-of-range values are
// treated as 1. The result may share data with `image` when no change is needed.
cv::Mat ApplyExifOrientation(const cv::Mat& image, int orientation);

// The size (width, height) of an image of `width` x `height` downscaled so that its long side
// is at most max_side (aspect ratio kept, each side at least 1); unchanged when max_side <= 0
// or the image already fits.
cv::Size WorkingSize(int width, int height, int max_side);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_IMAGE_READER_H_
