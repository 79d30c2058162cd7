#include "core/image/image_reader.h"

#include "core/image/image_header.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <system_error>
#include <utility>
#include <vector>

namespace reconduit {
namespace {

std::string Megapixels(std::int64_t pixels) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f megapixels", static_cast<double>(pixels) * 1e-6);
  return text;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height) + " pixels";
}

// Reads the whole file into *bytes after checking its size against the limit.
Status ReadFileBytes(const std::filesystem::path& path,
                     const ImageReaderOptions& options,
                     ImageInfo* info,
                     std::vector<std::uint8_t>* bytes) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    return Status::NotFound(error ? "cannot open the file (" + error.message() + ")"
                                  : std::string("not a regular file"));
  }
  const std::uintmax_t size = std::filesystem::file_size(path, error);
  if (error) return Status::NotFound("cannot open the file (" + error.message() + ")");
  info->file_bytes = static_cast<std::int64_t>(size);
  if (size == 0) return Status::InvalidArgument("the file is empty");
  if (size > static_cast<std::uintmax_t>(options.max_file_bytes)) {
    return Status::ResourceExhausted("the file is " + std::to_string(size) +
                                     " bytes; the maximum is " +
                                     std::to_string(options.max_file_bytes) + " bytes");
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) return Status::NotFound("cannot open the file");
  bytes->resize(static_cast<std::size_t>(size));
  file.read(reinterpret_cast<char*>(bytes->data()), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(file.gcount()) != size) {
    return Status::Internal("could not read the whole file");
  }
  return Status::Ok();
}

// Runs every check on `path` and decodes it. The pixels (oriented, at working size) are put
// in *pixels when it is non-null. Returns the record; its status says whether it was accepted.
ImageRecord LoadImage(const std::filesystem::path& path,
                      const ImageReaderOptions& options,
                      cv::Mat* pixels) {
  std::string error;
  THROW_CHECK(options.Check(&error)) << error;

  ImageRecord record;
  record.path = path;
  record.name = path.filename().string();
  ImageInfo& info = record.info;
  const auto refuse = [&record](const Status& status) {
    record.status = Status(status.code(), record.name + ": " + status.message());
    return record;
  };

  std::vector<std::uint8_t> bytes;
  if (Status status = ReadFileBytes(path, options, &info, &bytes); !status.ok()) {
    return refuse(status);
  }
  info.format = DetectImageFormat(bytes);
  if (info.format == ImageFormat::kUnknown) {
    return refuse(Status::InvalidArgument("not a JPEG, PNG or TIFF image"));
  }

  // Limits from the header, before anything is decoded.
  const Result<ImageHeader> header = ReadImageHeader(bytes);
  if (!header.ok()) return refuse(header.status());
  const std::int64_t num_pixels = std::int64_t{header->width} * header->height;
  if (num_pixels > options.max_pixels) {
    return refuse(Status::ResourceExhausted("image is " + SizeText(header->width, header->height) +
                                            " (" + Megapixels(num_pixels) + "); the maximum is " +
                                            Megapixels(options.max_pixels)));
  }
  if (std::min(header->width, header->height) < options.min_side) {
    return refuse(Status::InvalidArgument("image is " + SizeText(header->width, header->height) +
                                          "; the minimum is " + std::to_string(options.min_side) +
                                          " pixels per side"));
  }
  if (Status status = CheckImageComplete(bytes); !status.ok()) return refuse(status);

  const std::optional<ExifInfo> exif = ReadExif(bytes);
  info.orientation = exif && exif->orientation ? *exif->orientation : 1;

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
  if (stored.cols != header->width || stored.rows != header->height) {
    return refuse(
        Status::InvalidArgument("the decoded image is " + SizeText(stored.cols, stored.rows) +
                                " but the header says " + SizeText(header->width, header->height)));
  }

  const cv::Mat oriented = ApplyExifOrientation(stored, info.orientation);
  info.width = oriented.cols;
  info.height = oriented.rows;
  const cv::Size working = WorkingSize(info.width, info.height, options.max_side);
  info.working_width = working.width;
  info.working_height = working.height;
  if (options.read_exif && exif) {
    info.exif = exif;
    info.focal = FocalLengthPixelsFromExif(*exif, info.width, info.height);
  }
  if (pixels != nullptr) {
    if (working == oriented.size()) {
      *pixels = oriented;
    } else {
      cv::resize(oriented, *pixels, working, 0.0, 0.0, cv::INTER_AREA);
    }
  }
  record.status = Status::Ok();
  return record;
}

}  // namespace

bool ImageReaderOptions::Check(std::string* error) const {
  std::string message;
  if (min_side < 1) {
    message = "min_side = " + std::to_string(min_side) + "; it must be at least 1";
  } else if (max_pixels < std::int64_t{min_side} * min_side) {
    message = "max_pixels = " + std::to_string(max_pixels) + "; it must be at least min_side^2 = " +
              std::to_string(std::int64_t{min_side} * min_side);
  } else if (max_file_bytes < 1 || max_file_bytes > INT_MAX) {
    message = "max_file_bytes = " + std::to_string(max_file_bytes) + "; it must be in [1, " +
              std::to_string(INT_MAX) + "]";
  } else if (max_side < 0) {
    message = "max_side = " + std::to_string(max_side) + "; it must be 0 (full size) or positive";
  }
  if (message.empty()) return true;
  if (error != nullptr) *error = "ImageReaderOptions: " + message;
  return false;
}

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
  const int long_side = std::max(width, height);
  if (max_side <= 0 || long_side <= max_side) return cv::Size(width, height);
  const double scale = static_cast<double>(max_side) / long_side;
  const auto scaled = [scale](int side) {
    return std::max(1, static_cast<int>(std::lround(side * scale)));
  };
  return cv::Size(scaled(width), scaled(height));
}

}  // namespace reconduit
