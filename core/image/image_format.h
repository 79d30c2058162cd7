// Image format detection from a file's first bytes (its "magic number").
//
// The upload server uses this to answer 415 for files that are not photos, and ingest uses it
// to pick a parser, so it depends on nothing but the standard library and reads at most
// kImageFormatMagicBytes bytes. The file name and extension are never consulted: a PNG named
// "photo.jpg" is a PNG.
//
// Recognised signatures:
//   JPEG  FF D8 FF
//   PNG   89 50 4E 47 0D 0A 1A 0A
//   TIFF  49 49 2A 00 ("II", little-endian) or 4D 4D 00 2A ("MM", big-endian); classic TIFF
//         only: BigTIFF (version 43) is reported as unknown.
//
// Thread-safety: all functions are thread-safe.
#ifndef RECONDUIT_CORE_IMAGE_IMAGE_FORMAT_H_
#define RECONDUIT_CORE_IMAGE_IMAGE_FORMAT_H_

#include "core/util/status.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>

namespace reconduit {

enum class ImageFormat { kUnknown = 0, kJpeg, kPng, kTiff };

// How many leading bytes DetectImageFormat needs to recognise every supported format.
inline constexpr std::size_t kImageFormatMagicBytes = 8;

// "JPEG", "PNG", "TIFF" or "unknown".
std::string_view ImageFormatName(ImageFormat format);

// "image/jpeg", "image/png", "image/tiff", or "application/octet-stream" for unknown.
std::string_view ImageFormatMimeType(ImageFormat format);

// The file extension stored photos get, without the dot: "jpg", "png", "tif"; "" for unknown.
std::string_view ImageFormatExtension(ImageFormat format);

// Recognises the format from the first bytes of a file. Fewer bytes than a signature needs
// (including an empty span) give kUnknown.
ImageFormat DetectImageFormat(std::span<const std::uint8_t> first_bytes);

// Reads the first kImageFormatMagicBytes bytes of `path` and detects its format. A file that
// cannot be opened gives NotFound; a short or empty file gives kUnknown.
Result<ImageFormat> DetectImageFormatOfFile(const std::filesystem::path& path);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_IMAGE_FORMAT_H_
