// Image size and structural completeness read from the container, without decoding pixels.
//
// Why parse headers ourselves: cv::imread cannot tell the size of an image without decoding
// it, so a decompression bomb (a 100 KB PNG that claims 100000 x 100000 pixels) would be
// refused only after allocating tens of gigabytes. And libjpeg decodes a truncated JPEG
// "successfully", filling the missing rows with grey and printing a warning nobody sees.
// These parsers read the JPEG SOF segment, the PNG IHDR chunk and the TIFF IFD0 tags, and walk
// the file's structure to see that it is complete.
//
// Sizes here are as stored, before any EXIF orientation is applied.
//
// Thread-safety: all functions are thread-safe; they only read the given bytes.
#ifndef RECONDUIT_CORE_IMAGE_IMAGE_HEADER_H_
#define RECONDUIT_CORE_IMAGE_IMAGE_HEADER_H_

#include "core/image/image_format.h"
#include "core/util/status.h"

#include <cstdint>
#include <span>

namespace reconduit {

struct ImageHeader {
  ImageFormat format = ImageFormat::kUnknown;
  // Stored size in pixels (before EXIF orientation), as declared by the header.
  int width = 0;
  int height = 0;
};

// Parses the format and the stored size from the start of an image file. `bytes` may be the
// whole file or only a prefix: for JPEG and PNG a few kilobytes normally suffice (JPEG needs
// everything up to the SOF segment, which follows the EXIF block); TIFF may keep its IFD
// anywhere, so pass the whole file. Returns InvalidArgument with a message (no file name) when
// the format is unknown or the header is malformed or does not fit in `bytes`.
Result<ImageHeader> ReadImageHeader(std::span<const std::uint8_t> bytes);

// Checks that the whole file `bytes` is structurally complete for its format:
//   JPEG  every segment fits in the file and the last scan's entropy-coded data is followed
//         by an EOI marker (FF D9);
//   PNG   every chunk fits in the file and an IEND chunk is present;
//   TIFF  the IFD0 image data (strips or tiles) lies inside the file.
// Bytes after the JPEG EOI or the PNG IEND (some cameras and editors append data) are
// ignored, so such files pass. Returns OK, or InvalidArgument with a message (no file name)
// such as "truncated: the JPEG data ends before its end-of-image marker".
// CRCs and entropy-coded data are not verified; decoding does that.
Status CheckImageComplete(std::span<const std::uint8_t> bytes);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_IMAGE_IMAGE_HEADER_H_
