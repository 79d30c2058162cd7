// The photo header checks the server runs on every upload (core/image/image_header.h,
// image_format.h): format by magic bytes, stored size from the JPEG SOF / PNG IHDR / TIFF IFD0,
// and structural completeness, all without decoding.
#include "core/image/image_format.h"
#include "core/image/image_header.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>
#include <span>

using namespace reconduit;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const ImageFormat format = DetectImageFormat(bytes);
  const Result<ImageHeader> header = ReadImageHeader(bytes);
  if (header.ok()) {
    RECONDUIT_FUZZ_CHECK(header->format == format);
    RECONDUIT_FUZZ_CHECK(header->format != ImageFormat::kUnknown);
    RECONDUIT_FUZZ_CHECK(header->width > 0 && header->height > 0);
  } else {
    RECONDUIT_FUZZ_CHECK(!header.status().message().empty());
  }
  const Status complete = CheckImageComplete(bytes);
  if (complete.ok()) RECONDUIT_FUZZ_CHECK(format != ImageFormat::kUnknown);
  // A prefix is what the server reads first; it must never read past it.
  (void)ReadImageHeader(bytes.first(size / 2));
  return 0;
}
