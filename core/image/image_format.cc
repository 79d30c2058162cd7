#include "core/image/image_format.h"

#include <algorithm>
#include <array>
#include <fstream>

namespace reconduit {
namespace {

bool StartsWith(std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> prefix) {
  return bytes.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), bytes.begin());
}

}  // namespace

std::string_view ImageFormatName(ImageFormat format) {
  switch (format) {
    case ImageFormat::kJpeg:
      return "JPEG";
    case ImageFormat::kPng:
      return "PNG";
    case ImageFormat::kTiff:
      return "TIFF";
    case ImageFormat::kUnknown:
      break;
  }
  return "unknown";
}

std::string_view ImageFormatExtension(ImageFormat format) {
  switch (format) {
    case ImageFormat::kJpeg:
      return "jpg";
    case ImageFormat::kPng:
      return "png";
    case ImageFormat::kTiff:
      return "tif";
    case ImageFormat::kUnknown:
      break;
  }
  return "";
}

std::string_view ImageFormatMimeType(ImageFormat format) {
  switch (format) {
    case ImageFormat::kJpeg:
      return "image/jpeg";
    case ImageFormat::kPng:
      return "image/png";
    case ImageFormat::kTiff:
      return "image/tiff";
    case ImageFormat::kUnknown:
      break;
  }
  return "application/octet-stream";
}

ImageFormat DetectImageFormat(std::span<const std::uint8_t> first_bytes) {
  static constexpr std::array<std::uint8_t, 3> kJpeg = {0xFF, 0xD8, 0xFF};
  static constexpr std::array<std::uint8_t, 8> kPng = {0x89, 0x50, 0x4E, 0x47,
                                                       0x0D, 0x0A, 0x1A, 0x0A};
  static constexpr std::array<std::uint8_t, 4> kTiffLittle = {0x49, 0x49, 0x2A, 0x00};
  static constexpr std::array<std::uint8_t, 4> kTiffBig = {0x4D, 0x4D, 0x00, 0x2A};
  if (StartsWith(first_bytes, kJpeg)) return ImageFormat::kJpeg;
  if (StartsWith(first_bytes, kPng)) return ImageFormat::kPng;
  if (StartsWith(first_bytes, kTiffLittle) || StartsWith(first_bytes, kTiffBig)) {
    return ImageFormat::kTiff;
  }
  return ImageFormat::kUnknown;
}

Result<ImageFormat> DetectImageFormatOfFile(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return Status::NotFound("cannot open " + path.string());
  std::array<char, kImageFormatMagicBytes> buffer{};
  file.read(buffer.data(), buffer.size());
  const auto count = static_cast<std::size_t>(file.gcount());
  return DetectImageFormat(
      std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(buffer.data()), count));
}

}  // namespace reconduit
