// Small pictures of depth and quality maps for the report and the page.
//
// Depth: the turbo colour map from near (red) to far (blue) over the 2nd..98th percentile of
// the map's depths, so one far outlier does not wash the picture out; empty pixels black.
// Quality (ARC3D's "how many views agree"): black where empty, dark red where only the photo
// itself has the depth (dropped by fusion), then from orange to green as 2, 3, ... views
// agree, full green from `max_views` on.
#ifndef RECONDUIT_CORE_MVS_DENSE_PREVIEWS_H_
#define RECONDUIT_CORE_MVS_DENSE_PREVIEWS_H_

#include <opencv2/core.hpp>

namespace reconduit {

// `depth` CV_32FC1 (0 where empty); returns CV_8UC3 BGR no larger than max_side (long side).
cv::Mat RenderDepthPreview(const cv::Mat& depth, int max_side);

// `quality` CV_8UC1; returns CV_8UC3 BGR no larger than max_side (long side).
cv::Mat RenderQualityPreview(const cv::Mat& quality, int max_views, int max_side);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_MVS_DENSE_PREVIEWS_H_
