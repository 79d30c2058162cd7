// Camera metadata from EXIF (via exiv2) and the focal length prior derived from it.
//
// EXIF is untrusted input: a missing, malformed or unreadable block simply means "no EXIF";
// nothing here throws on bad metadata. exiv2's own warnings on stderr are silenced.
//
// Focal length in pixels (FocalLengthPixelsFromExif) is a prior for self-calibration, used in
// this order:
//  1. FocalLengthIn35mmFilm: f_px = f35 / 36 * max(width, height). Convention: 36 mm is the
//     long side of a full-frame (36 x 24 mm) sensor and maps to the image's long side. Makers
//     often compute the 35 mm equivalent from the diagonal instead, so for a 4:3 sensor this is
//     about 4 % too long: good enough for a prior, not for metrology.
//  2. FocalLength (mm) with FocalPlaneXResolution (pixels per unit; Y when X is absent) and
//     FocalPlaneResolutionUnit (2 = inch, 3 = cm, 4 = mm, 5 = µm; EXIF's default is inch;
//     1 = "no unit" is unusable): f_px = f_mm * resolution / unit_mm. The focal-plane
//     resolution refers to the image at the size the camera wrote (PixelX/YDimension), so the
//     result is scaled by max(width, height) / max(PixelXDimension, PixelYDimension) when the
//     image was resized afterwards.
// Otherwise the prior is absent.
//
// Thread-safety: ReadExif may be called concurrently on different inputs (exiv2 is initialised
// once, with a lock for its XMP toolkit); the other functions are pure.
#ifndef RECONDUIT_CORE_IMAGE_EXIF_H_
#define RECONDUIT_CORE_IMAGE_EXIF_H_

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace reconduit {

// The EXIF fields ingest uses. Every numeric field is absent when the tag is missing or its
// value is unusable (zero, negative, not finite).
struct ExifInfo {
  // Exif.Image.Make / Model, trimmed; empty when absent.
  std::string camera_make;
  std::string camera_model;
  // Exif.Image.Orientation, 1..8 as in the EXIF/TIFF spec (1 = as stored, 6 = the stored
  // image must be rotated 90° clockwise to display); absent when missing or out of range.
  std::optional<int> orientation;
  // Exif.Photo.FocalLength, lens focal length in millimetres.
  std::optional<double> focal_length_mm;
  // Exif.Photo.FocalLengthIn35mmFilm, 35 mm-equivalent focal length in millimetres.
  std::optional<double> focal_length_35mm;
  // Exif.Photo.FocalPlaneX/YResolution: pixels per FocalPlaneResolutionUnit on the sensor.
  std::optional<double> focal_plane_x_resolution;
  std::optional<double> focal_plane_y_resolution;
  // Exif.Photo.FocalPlaneResolutionUnit as stored: 1 none, 2 inch, 3 cm, 4 mm, 5 µm.
  std::optional<int> focal_plane_resolution_unit;
  // Exif.Photo.PixelX/YDimension: image size in pixels when the camera wrote the file.
  std::optional<int> pixel_width;
  std::optional<int> pixel_height;
};

// Which EXIF fields a focal length in pixels came from.
enum class FocalSource {
  kFocalLength35mm,       // FocalLengthIn35mmFilm and the image's long side.
  kFocalPlaneResolution,  // FocalLength and FocalPlaneX/YResolution with its unit.
};

std::string_view FocalSourceName(FocalSource source);  // "35mm_equivalent", "focal_plane".

struct FocalLengthPixels {
  double focal_px = 0.0;  // Focal length in pixels of the image of the given size.
  FocalSource source = FocalSource::kFocalLength35mm;
};

// Reads the EXIF block of an image held in memory (JPEG, PNG or TIFF bytes). Returns nothing
// when the data has no EXIF block or exiv2 cannot read it. Never throws on bad data.
std::optional<ExifInfo> ReadExif(std::span<const std::uint8_t> file_bytes);

// Millimetres per FocalPlaneResolutionUnit code (2 -> 25.4, 3 -> 10, 4 -> 1, 5 -> 0.001);
// nothing for 1 ("no absolute unit") and unknown codes.
std::optional<double> FocalPlaneUnitMillimetres(int unit);

// Focal length in pixels for an image of `width` x `height` pixels, sizes as displayed (after
// EXIF orientation; only the long side matters, so the stored size gives the same answer).
// See the file comment for the rules. Absent when no usable combination of fields exists.
std::optional<FocalLengthPixels> FocalLengthPixelsFromExif(const ExifInfo& exif,
                                                           int width,
                                                           int height);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_EXIF_H_
