// Byte ranges (RFC 9110 14) and entity-tag comparison (RFC 9110 8.8.3, 13.1.2) for downloads.
//
// Only what result.zip needs: a single range per request. A Range header the server does not
// understand or chooses not to serve (another unit, a syntax error, several ranges) is ignored
// and the whole file is sent, as RFC 9110 14.2 allows; a well-formed range that lies wholly
// outside the file is "unsatisfiable" (416 with `Content-Range: bytes */<size>`).
//
// Pure string processing; thread-safe.
#ifndef RECONDUIT_SERVER_HTTP_RANGE_H_
#define RECONDUIT_SERVER_HTTP_RANGE_H_

#include "server/http/response.h"

#include <cstdint>
#include <string>
#include <string_view>

namespace reconduit::server {

struct RangeRequest {
  enum class Kind {
    kWhole,          // No usable Range header: send the whole representation (200).
    kPartial,        // Send `slice` (206).
    kUnsatisfiable,  // 416.
  };
  Kind kind = Kind::kWhole;
  // For kPartial: offset and length within [0, size); length >= 1.
  FileSlice slice;
};

// Interprets a Range header value for a representation of `size` bytes:
//   "bytes=0-499" first 500 bytes; "bytes=500-" from 500 to the end; "bytes=-500" the last 500
//   bytes (the whole file when it is shorter); a last position past the end is clamped.
// Unsatisfiable: a first position >= size, or a suffix length of 0 (also any range of an empty
// file). Whole: anything malformed, a last position before the first, or more than one range.
RangeRequest ParseRangeHeader(std::string_view header, std::uint64_t size);

// "bytes 0-499/1234" for a partial response.
std::string ContentRangeHeader(const FileSlice& slice, std::uint64_t size);

// True when an If-None-Match (or If-Range) header value lists `etag` (a quoted entity tag such
// as "\"abc\""), using the weak comparison of RFC 9110 8.8.3.2: a W/ prefix on either side is
// ignored. "*" matches any existing representation.
bool EntityTagListMatches(std::string_view header, std::string_view etag);

// True when an If-Range header value is `etag` by the strong comparison RFC 9110 13.1.5
// requires: both tags strong (no W/ prefix) and identical. A date, a list or a weak tag never
// matches, so the client gets the whole representation.
bool IfRangeMatches(std::string_view header, std::string_view etag);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_RANGE_H_
