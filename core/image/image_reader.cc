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

  cv::Mat stored;
  try {
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, bytes.data());
    stored = cv::imdecode(buffer, cv::IMREAD_COLOR | cv::IMREAD_IGNORE_ORIENTATION);
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
  const int declared_width = swapped ? info.height : info.width;
  const int declared_height = swapped ? info.width : info.height;
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

Result<cv::Mat> ReadImage(const std::filesystem::path& path, const ImageReaderOptions& options) {
  cv::Mat pixels;
  ImageRecord record = LoadImage(path, options, &pixels);
  if (!record.status.ok()) return record.status;
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
