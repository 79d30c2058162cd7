#include "core/image/image_check.h"

#include "core/image/image_header.h"
#include "core/util/logging.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <system_error>
#include <tuple>
#include <utility>

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

// The size limits, from the header alone.
Status CheckDeclaredSize(const ImageHeader& header, const ImageReaderOptions& options) {
  const std::int64_t num_pixels = std::int64_t{header.width} * header.height;
  if (num_pixels > options.max_pixels) {
    return Status::ResourceExhausted("image is " + SizeText(header.width, header.height) + " (" +
                                     Megapixels(num_pixels) + "); the maximum is " +
                                     Megapixels(options.max_pixels));
  }
  if (std::min(header.width, header.height) < options.min_side) {
    return Status::InvalidArgument("image is " + SizeText(header.width, header.height) +
                                   "; the minimum is " + std::to_string(options.min_side) +
                                   " pixels per side");
  }
  return Status::Ok();
}

// Fills the displayed size, working size, orientation, EXIF and focal prior of an accepted
// photo from its stored size and EXIF block.
void DescribeAcceptedImage(const ImageHeader& header,
                           const std::optional<ExifInfo>& exif,
                           const ImageReaderOptions& options,
                           ImageInfo* info) {
  info->orientation = exif && exif->orientation ? *exif->orientation : 1;
  // Orientations 5..8 turn the image by a quarter (see ApplyExifOrientation).
  const bool swaps_sides = info->orientation >= 5 && info->orientation <= 8;
  info->width = swaps_sides ? header.height : header.width;
  info->height = swaps_sides ? header.width : header.height;
  std::tie(info->working_width, info->working_height) =
      WorkingSideLengths(info->width, info->height, options.max_side);
  if (options.read_exif && exif) {
    info->exif = exif;
    info->focal = FocalLengthPixelsFromExif(*exif, info->width, info->height);
  }
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

std::string ImageRecord::ReasonWithoutName() const {
  if (accepted()) return "";
  std::string reason = status.message();
  const std::string prefix = name + ": ";
  if (reason.rfind(prefix, 0) == 0) reason.erase(0, prefix.size());
  return reason.empty() ? "rejected" : reason;
}

PhotoMetadata ImageRecord::Metadata() const {
  PhotoMetadata photo;
  photo.bytes = info.file_bytes;
  if (info.width > 0 && info.height > 0) {
    photo.width = info.width;
    photo.height = info.height;
  }
  if (info.focal) {
    photo.exif_focal_px = info.focal->focal_px;
    photo.focal_source = std::string(FocalSourceName(info.focal->source));
  }
  if (info.exif) {
    photo.make = info.exif->camera_make;
    photo.model = info.exif->camera_model;
  }
  photo.accepted = accepted();
  photo.reason = ReasonWithoutName();
  return photo;
}

ImageRecord InspectImageHeader(const std::filesystem::path& path,
                               const ImageReaderOptions& options,
                               std::vector<std::uint8_t>* bytes_out) {
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
  const Result<ImageHeader> header = ReadImageHeader(bytes);
  if (!header.ok()) return refuse(header.status());
  if (Status status = CheckDeclaredSize(*header, options); !status.ok()) return refuse(status);
  if (Status status = CheckImageComplete(bytes); !status.ok()) return refuse(status);

  DescribeAcceptedImage(*header, ReadExif(bytes), options, &info);
  record.status = Status::Ok();
  if (bytes_out != nullptr) *bytes_out = std::move(bytes);
  return record;
}

std::pair<int, int> WorkingSideLengths(int width, int height, int max_side) {
  const int long_side = std::max(width, height);
  if (max_side <= 0 || long_side <= max_side) return {width, height};
  const double scale = static_cast<double>(max_side) / long_side;
  const auto scaled = [scale](int side) {
    return std::max(1, static_cast<int>(std::lround(side * scale)));
  };
  return {scaled(width), scaled(height)};
}

}  // namespace reconduit
