// Range headers and entity-tag comparison (server/http/range.h) for downloads.
// Input: 8 bytes of representation size (little-endian; shorter inputs give small sizes),
// then the header value, which also serves as If-None-Match / If-Range against a fixed tag.
#include "server/http/range.h"

#include "fuzz/fuzz_util.h"
#include <cstddef>
#include <cstdint>
#include <cstring>

using namespace reconduit::server;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::uint64_t file_size = 0;
  const std::size_t size_bytes = size < 8 ? size / 2 : 8;
  for (std::size_t i = 0; i < size_bytes; ++i) file_size |= std::uint64_t{data[i]} << (8 * i);
  const std::string_view header = reconduit::fuzz::AsText(data + size_bytes, size - size_bytes);

  const RangeRequest range = ParseRangeHeader(header, file_size);
  if (range.kind == RangeRequest::Kind::kPartial) {
    RECONDUIT_FUZZ_CHECK(range.slice.length >= 1);
    RECONDUIT_FUZZ_CHECK(range.slice.offset < file_size);
    RECONDUIT_FUZZ_CHECK(range.slice.length <= file_size - range.slice.offset);
    const std::string content_range = ContentRangeHeader(range.slice, file_size);
    RECONDUIT_FUZZ_CHECK(content_range.rfind("bytes ", 0) == 0);
  }

  for (const std::string_view etag : {"\"abc\"", "W/\"abc\"", "\"\""}) {
    const bool weak = EntityTagListMatches(header, etag);
    const bool strong = IfRangeMatches(header, etag);
    // A strong match is also a weak one.
    RECONDUIT_FUZZ_CHECK(!strong || weak);
  }
  return 0;
}
