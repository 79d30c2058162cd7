#include "core/image/image_reader.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace reconduit {
namespace {

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height) + " pixels";
}

// The JPEG scale-on-decode factor for an image wanted at its working size: the largest of 8, 4
// and 2 whose reduced image (each side divided, rounded up, as libjpeg does) still covers the
// working size, so that only a downscale remains; 1 for other formats, at full size, or when
// no pixels are wanted (InspectImage proves the full image decodes).
int DecodeReduction(const ImageInfo& info, bool want_pixels) {
  if (!want_pixels || info.format != ImageFormat::kJpeg) return 1;
  for (const int factor : {8, 4, 2}) {
    const int width = (info.width + factor - 1) / factor;
    const int height = (info.height + factor - 1) / factor;
    if (width >= info.working_width && height >= info.working_height) return factor;
  }
  return 1;
}

int DecodeFlags(int reduction, bool grey) {
  const int flags = grey ? (reduction == 8   ? cv::IMREAD_REDUCED_GRAYSCALE_8
                            : reduction == 4 ? cv::IMREAD_REDUCED_GRAYSCALE_4
                            : reduction == 2 ? cv::IMREAD_REDUCED_GRAYSCALE_2
                                             : cv::IMREAD_GRAYSCALE)
                         : (reduction == 8   ? cv::IMREAD_REDUCED_COLOR_8
                            : reduction == 4 ? cv::IMREAD_REDUCED_COLOR_4
                            : reduction == 2 ? cv::IMREAD_REDUCED_COLOR_2
                                             : cv::IMREAD_COLOR);
  return flags | cv::IMREAD_IGNORE_ORIENTATION;
}

// Runs every header check on `path` (InspectImageHeader), then decodes it. The pixels
// (oriented, at working size) are put in *pixels when it is non-null. Returns the record; its
// status says whether it was accepted.
ImageRecord LoadImage(const std::filesystem::path& path,
                      const ImageReaderOptions& options,
                      cv::Mat* pixels) {
  std::vector<std::uint8_t> bytes;
  ImageRecord record = InspectImageHeader(path, options, &bytes);
  if (!record.accepted()) return record;
  ImageInfo& info = record.info;
  const auto refuse = [&record](const Status& status) {
    // Only what the header says survives a refusal: the size is known once decoded.
    ImageInfo& refused = record.info;
    refused = ImageInfo{.format = refused.format,
                        .file_bytes = refused.file_bytes,
                        .orientation = refused.orientation};
    record.status = Status(status.code(), record.name + ": " + status.message());
    return record;
  };

  // A JPEG much larger than its working size is decoded at 1/2, 1/4 or 1/8 scale (libjpeg
  // scales in the inverse DCT): a 100 Mpx photo wanted at 3200 px never exists at full size.
  const int reduction = DecodeReduction(info, pixels != nullptr);
  cv::Mat stored;
  try {
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, bytes.data());
    // Without pixels wanted (InspectImage), one grey channel proves the file decodes as well.
    stored = cv::imdecode(buffer, DecodeFlags(reduction, options.grey || pixels == nullptr));
  } catch (const cv::Exception& e) {
    return refuse(Status::InvalidArgument("the " + std::string(ImageFormatName(info.format)) +
                                          " data could not be decoded (" + e.err + ")"));
  }
  std::vector<std::uint8_t>().swap(bytes);  // Free the file before orienting and resizing.
  if (stored.empty()) {
    return refuse(Status::InvalidArgument("the " + std::string(ImageFormatName(info.format)) +
                                          " data could not be decoded (corrupt or unsupported)"));
  }
  // The header's stored size: orientations 5..8 swapped it to give info's displayed size.
  const bool swapped = info.orientation >= 5 && info.orientation <= 8;
  const int declared_width = ((swapped ? info.height : info.width) + reduction - 1) / reduction;
  const int declared_height = ((swapped ? info.width : info.height) + reduction - 1) / reduction;
  if (stored.cols != declared_width || stored.rows != declared_height) {
    return refuse(Status::InvalidArgument(
        "the decoded image is " + SizeText(stored.cols, stored.rows) + " but the header says " +
        SizeText(declared_width, declared_height)));
  }
  const cv::Mat oriented = ApplyExifOrientation(stored, info.orientation);
  if (pixels != nullptr) {
    const cv::Size working(info.working_width, info.working_height);
    if (working == oriented.size()) {
      *pixels = oriented;
    } else {
      cv::resize(oriented, *pixels, working, 0.0, 0.0, cv::INTER_AREA);
    }
  }
  return record;
}

}  // namespace

ImageRecord InspectImage(const std::filesystem::path& path, const ImageReaderOptions& options) {
  return LoadImage(path, options, nullptr);
}

Result<cv::Mat> ReadImage(const std::filesystem::path& path,
                          const ImageReaderOptions& options,
                          ImageInfo* info) {
  cv::Mat pixels;
  ImageRecord record = LoadImage(path, options, &pixels);
  if (!record.status.ok()) return record.status;
  if (info != nullptr) *info = record.info;
  return pixels;
}

cv::Mat ApplyExifOrientation(const cv::Mat& image, int orientation) {
  cv::Mat result;
  switch (orientation) {
    case 2:  // Mirrored horizontally.
      cv::flip(image, result, 1);
      break;
    case 3:  // Rotated 180°.
      cv::rotate(image, result, cv::ROTATE_180);
      break;
    case 4:  // Mirrored vertically.
      cv::flip(image, result, 0);
      break;
    case 5:  // Mirrored along the main diagonal.
      cv::transpose(image, result);
      break;
    case 6:  // Stored rotated 90° counter-clockwise: rotate clockwise to display.
      cv::rotate(image, result, cv::ROTATE_90_CLOCKWISE);
      break;
    case 7: {  // Mirrored along the anti-diagonal.
      cv::Mat transposed;
      cv::transpose(image, transposed);
      cv::flip(transposed, result, -1);
      break;
    }
    case 8:  // Stored rotated 90° clockwise.
      cv::rotate(image, result, cv::ROTATE_90_COUNTERCLOCKWISE);
      break;
    default:
      return image;
  }
  return result;
}

cv::Size WorkingSize(int width, int height, int max_side) {
  const auto [working_width, working_height] = WorkingSideLengths(width, height, max_side);
  return cv::Size(working_width, working_height);
}

}  // namespace reconduit
