#include "core/pipeline/stages/features_stage.h"

#include "core/feature/sift.h"
#include "core/image/huge_page_allocator.h"
#include "core/image/image_reader.h"
#include "core/pipeline/stages/ingest_stage.h"
#include "core/util/logging.h"
#include "core/util/parallel.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <stdexcept>

namespace reconduit {

std::filesystem::path FeaturesPath(const Workspace& workspace, int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "%05d.feat", index);
  return workspace.StageDir("features") / name;
}

Result<FeatureSet> ReadImageFeatures(const Workspace& workspace, int index) {
  return ReadFeatures(FeaturesPath(workspace, index));
}

StageResult FeaturesStage::Run(StageContext& context) const {
  auto images = ReadIngestedImages(context.workspace);
  if (!images.ok()) return StageResult::Failed(images.status().message());
  std::vector<const IngestedImage*> accepted;
  for (const IngestedImage& image : *images) {
    if (image.photo.accepted) accepted.push_back(&image);
  }

  SiftOptions sift;
  sift.max_image_side = context.options.max_image_side;
  sift.max_features = context.options.max_features;
  sift.min_features = context.options.min_features;
  ImageReaderOptions reader;
  reader.min_side = context.options.min_image_side;
  reader.max_pixels = context.options.max_image_pixels;
  reader.read_exif = false;
  reader.grey = true;
  // Read at the working size: a large JPEG is decoded at reduced scale (image_reader.h), so
  // its full-size pixels never exist; SIFT reports in the original's pixels.
  reader.max_side = sift.max_image_side;

  // OpenCV's own threads would compete with ours: one OpenCV thread per photo in flight.
  // SIFT's pyramids on huge pages: see huge_page_allocator.h (a 4x speed-up here).
  ScopedHugePageMatAllocator huge_pages;
  const int previous_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);
  std::atomic<std::size_t> total{0};
  std::atomic<std::size_t> fewest{SIZE_MAX};
  std::atomic<int> adapted{0};    // Photos detected again at a lower contrast threshold.
  std::atomic<int> upsampled{0};  // Of those, photos detected at twice their size.
  context.progress.Restart(accepted.size(), "photos");
  try {
    ParallelFor(
        0, accepted.size(),
        [&](std::size_t k) {
          context.cancel.ThrowIfCanceled();
          const IngestedImage& image = *accepted[k];
          ImageInfo info;
          auto pixels = ReadImage(image.path, reader, &info);
          if (!pixels.ok()) {
            // Ingest read it: the file changed or went away under the running job.
            throw std::runtime_error("the photo " + image.name + " can no longer be read (" +
                                     pixels.status().message() +
                                     "); it was readable when the job started");
          }
          SiftDetection detection;
          const FeatureSet features =
              ExtractSiftFeatures(*pixels, sift, cv::Size(info.width, info.height), &detection);
          if (detection.passes > 1) {
            ++adapted;
            if (detection.upsampled) ++upsampled;
            LOG_INFO << "features: " << image.name
                     << " is short of features: " << detection.candidates << " candidates after "
                     << detection.passes << " passes (contrast threshold "
                     << detection.contrast_threshold
                     << (detection.upsampled ? ", detected at twice its size" : "") << ")";
          }
          const Status written =
              WriteFeatures(FeaturesPath(context.workspace, image.index), features);
          THROW_CHECK(written.ok()) << written.message();
          total += features.size();
          std::size_t current = fewest.load();
          while (features.size() < current &&
                 !fewest.compare_exchange_weak(current, features.size())) {
          }
          LOG_DEBUG << "features: " << image.name << ": " << features.size();
          context.progress.Advance();
        },
        context.options.num_threads);
  } catch (...) {
    cv::setNumThreads(previous_cv_threads);
    throw;
  }
  cv::setNumThreads(previous_cv_threads);
  const double mean = accepted.empty() ? 0.0 : static_cast<double>(total) / accepted.size();
  LOG_INFO << "features: " << total.load() << " in " << accepted.size() << " photos (mean "
           << static_cast<int>(mean) << ", fewest " << (accepted.empty() ? 0 : fewest.load())
           << "; " << adapted.load() << " short of features detected again, " << upsampled.load()
           << " of them at twice their size)";
  return StageResult::Success({{"photos", accepted.size()},
                               {"features", total.load()},
                               {"mean_per_photo", mean},
                               {"adapted_photos", adapted.load()},
                               {"upsampled_photos", upsampled.load()}});
}

}  // namespace reconduit
