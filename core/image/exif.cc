#include "core/image/exif.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <stdexcept>

// exiv2 0.27's public API is built on std::auto_ptr, deprecated since C++11.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>

namespace reconduit {
namespace {

// The XMP toolkit inside exiv2 is not thread-safe; exiv2 serialises it through this lock.
void LockXmpToolkit(void* mutex, bool lock) {
  if (lock) {
    static_cast<std::mutex*>(mutex)->lock();
  } else {
    static_cast<std::mutex*>(mutex)->unlock();
  }
}

void InitExiv2Once() {
  static std::once_flag once;
  static std::mutex xmp_mutex;
  std::call_once(once, [] {
    Exiv2::LogMsg::setLevel(Exiv2::LogMsg::mute);
    Exiv2::XmpParser::initialize(&LockXmpToolkit, &xmp_mutex);
  });
}

const Exiv2::Exifdatum* FindDatum(const Exiv2::ExifData& data, const char* key) {
  const auto it = data.findKey(Exiv2::ExifKey(key));
  if (it == data.end() || it->count() == 0) return nullptr;
  return &*it;
}

std::optional<double> PositiveNumber(const Exiv2::ExifData& data, const char* key) {
  const Exiv2::Exifdatum* datum = FindDatum(data, key);
  if (datum == nullptr) return std::nullopt;
  const Exiv2::Rational value = datum->toRational(0);
  if (value.second == 0) return std::nullopt;
  const double number = static_cast<double>(value.first) / static_cast<double>(value.second);
  if (!std::isfinite(number) || number <= 0.0) return std::nullopt;
  return number;
}

std::optional<int> PositiveInteger(const Exiv2::ExifData& data, const char* key) {
  const Exiv2::Exifdatum* datum = FindDatum(data, key);
  if (datum == nullptr) return std::nullopt;
  const long value = datum->toLong(0);
  if (value <= 0 || value > 1'000'000'000) return std::nullopt;
  return static_cast<int>(value);
}

std::string TrimmedString(const Exiv2::ExifData& data, const char* key) {
  const Exiv2::Exifdatum* datum = FindDatum(data, key);
  if (datum == nullptr) return "";
  std::string text = datum->toString();
  const auto is_blank = [](char c) { return c == '\0' || c == ' ' || c == '\t' || c == '\n'; };
  while (!text.empty() && is_blank(text.back())) text.pop_back();
  const auto first = std::find_if_not(text.begin(), text.end(), is_blank);
  return std::string(first, text.end());
}

ExifInfo ExtractExifInfo(const Exiv2::ExifData& data) {
  ExifInfo info;
  info.camera_make = TrimmedString(data, "Exif.Image.Make");
  info.camera_model = TrimmedString(data, "Exif.Image.Model");
  if (const auto orientation = PositiveInteger(data, "Exif.Image.Orientation");
      orientation && *orientation <= 8) {
    info.orientation = orientation;
  }
  info.focal_length_mm = PositiveNumber(data, "Exif.Photo.FocalLength");
  info.focal_length_35mm = PositiveNumber(data, "Exif.Photo.FocalLengthIn35mmFilm");
  info.focal_plane_x_resolution = PositiveNumber(data, "Exif.Photo.FocalPlaneXResolution");
  info.focal_plane_y_resolution = PositiveNumber(data, "Exif.Photo.FocalPlaneYResolution");
  info.focal_plane_resolution_unit = PositiveInteger(data, "Exif.Photo.FocalPlaneResolutionUnit");
  info.pixel_width = PositiveInteger(data, "Exif.Photo.PixelXDimension");
  info.pixel_height = PositiveInteger(data, "Exif.Photo.PixelYDimension");
  return info;
}

}  // namespace

std::string_view FocalSourceName(FocalSource source) {
  switch (source) {
    case FocalSource::kFocalLength35mm:
      return "35mm_equivalent";
    case FocalSource::kFocalPlaneResolution:
      return "focal_plane";
  }
  return "unknown";
}

std::optional<ExifInfo> ReadExif(std::span<const std::uint8_t> file_bytes) {
  if (file_bytes.empty()) return std::nullopt;
  InitExiv2Once();
  try {
    Exiv2::Image::AutoPtr image =
        Exiv2::ImageFactory::open(file_bytes.data(), static_cast<long>(file_bytes.size()));
    if (image.get() == nullptr) return std::nullopt;
    image->readMetadata();
    const Exiv2::ExifData& data = image->exifData();
    if (data.empty()) return std::nullopt;
    return ExtractExifInfo(data);
  } catch (const Exiv2::AnyError&) {
    return std::nullopt;  // Unreadable EXIF is no EXIF.
  } catch (const std::exception&) {
    // exiv2 may also throw standard exceptions (std::bad_alloc, std::out_of_range) on
    // hostile metadata; the photo itself may still be fine.
    return std::nullopt;
  }
}

#pragma GCC diagnostic pop

std::optional<double> FocalPlaneUnitMillimetres(int unit) {
  switch (unit) {
    case 2:
      return 25.4;
    case 3:
      return 10.0;
    case 4:
      return 1.0;
    case 5:
      return 0.001;
    default:
      return std::nullopt;
  }
}

std::optional<FocalLengthPixels> FocalLengthPixelsFromExif(const ExifInfo& exif,
                                                           int width,
                                                           int height) {
  const int long_side = std::max(width, height);
  if (long_side <= 0) return std::nullopt;
  const auto usable = [](double f) { return std::isfinite(f) && f > 0.0; };

  if (exif.focal_length_35mm) {
    const double focal_px = *exif.focal_length_35mm / 36.0 * long_side;
    if (usable(focal_px)) return FocalLengthPixels{focal_px, FocalSource::kFocalLength35mm};
  }

  const std::optional<double> resolution =
      exif.focal_plane_x_resolution ? exif.focal_plane_x_resolution : exif.focal_plane_y_resolution;
  // EXIF 2.3: FocalPlaneResolutionUnit defaults to 2 (inch) when absent.
  const std::optional<double> unit_mm =
      FocalPlaneUnitMillimetres(exif.focal_plane_resolution_unit.value_or(2));
  if (exif.focal_length_mm && resolution && unit_mm) {
    double scale = 1.0;
    if (exif.pixel_width && exif.pixel_height) {
      scale = static_cast<double>(long_side) / std::max(*exif.pixel_width, *exif.pixel_height);
    }
    const double focal_px = *exif.focal_length_mm * (*resolution / *unit_mm) * scale;
    if (usable(focal_px)) return FocalLengthPixels{focal_px, FocalSource::kFocalPlaneResolution};
  }
  return std::nullopt;
}

}  // namespace reconduit
