// A streaming multipart/form-data parser (RFC 7578 on the RFC 2046 multipart syntax).
//
// The body is pushed in arbitrary chunks (as they come off the socket; a chunk border may fall
// anywhere, even inside a boundary) and each part is reported through callbacks: its headers
// once, then its content in pieces, then its end. Memory use is bounded by the part-header
// limit plus the boundary length plus the largest chunk fed: a multi-gigabyte part streams
// straight into a file.
//
//   Result<std::string> boundary = MultipartBoundary(ctx.Header("Content-Type").value_or(""));
//   MultipartParser parser(*boundary, {
//       .on_part_begin = [&](const MultipartPart& part) { ...open a temp file...; return
//       Status::Ok(); }, .on_part_data = [&](std::string_view data) { ...write...; return
//       Status::Ok(); }, .on_part_end = [&] { ...close, validate...; return Status::Ok(); }});
//   for each chunk: if (Status s = parser.Feed(chunk); !s.ok()) -> 400 (or the callback's error)
//   at the end:     if (Status s = parser.Finish(); !s.ok()) -> 400 (truncated body)
//
// Syntax handled: the preamble before the first boundary and the epilogue after the closing one
// are ignored; the first delimiter may start the body without a leading CRLF; transport padding
// (spaces, tabs) after a boundary is allowed; header names are case-insensitive; a part without
// a Content-Type is text/plain (RFC 7578 4.4). Every part needs `Content-Disposition: form-data`
// with a `name` (RFC 7578 4.2); `filename` is reported verbatim. The file name is client input:
// it may contain "../", '/', '\' or be absolute. Use it for display only, never as a path.
//
// Errors (kInvalidArgument, or whatever a callback returned): a missing or malformed delimiter
// line, a part header block over `max_header_bytes`, a malformed header line, a missing
// Content-Disposition or name, more than `max_parts` parts, and a body that ends before the
// closing delimiter (reported by Finish()). After an error the parser stays failed and returns
// the same Status from every later call.
//
// Not thread-safe; one parser per request.
#ifndef RECONDUIT_SERVER_HTTP_MULTIPART_H_
#define RECONDUIT_SERVER_HTTP_MULTIPART_H_

#include "core/util/status.h"
#include "server/http/url.h"

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace reconduit::server {

// The headers of one part.
struct MultipartPart {
  // The form field name (Content-Disposition `name`), e.g. "images".
  std::string name;
  // The client's file name (Content-Disposition `filename`, or a decoded RFC 5987 `filename*`),
  // unset for plain fields. Untrusted: display only.
  std::optional<std::string> filename;
  // The part's Content-Type, lower-cased type/subtype with parameters as sent; "text/plain"
  // when absent.
  std::string content_type = "text/plain";
  // All part headers in order, names as sent.
  KeyValues headers;
};

// The boundary of a `multipart/form-data; boundary=...` Content-Type (quoted or not).
// kInvalidArgument when the type is not multipart/form-data or the boundary is missing, empty,
// longer than 70 characters (RFC 2046 5.1.1) or contains CR or LF.
Result<std::string> MultipartBoundary(std::string_view content_type);

class MultipartParser {
 public:
  struct Options {
    // Maximum size in bytes of one part's header block (the lines between the boundary and the
    // empty line). Browsers send a few hundred bytes.
    std::size_t max_header_bytes = 16 * 1024;
    // Maximum number of parts in one body, so a body of tiny parts cannot flood the callbacks.
    std::size_t max_parts = 10000;
  };

  // Each callback returns Status::Ok() to continue; any other Status stops parsing and is
  // returned from Feed(). Unset callbacks are skipped.
  struct Callbacks {
    std::function<Status(const MultipartPart& part)> on_part_begin;
    // Content bytes of the current part, in order, never empty.
    std::function<Status(std::string_view data)> on_part_data;
    std::function<Status()> on_part_end;
  };

  MultipartParser(std::string boundary, Callbacks callbacks);
  MultipartParser(std::string boundary, Callbacks callbacks, Options options);

  // Consumes the next piece of the body (any size, including empty).
  Status Feed(std::string_view chunk);
  // Declares the end of the body: OK only if the closing delimiter was seen.
  Status Finish();

  // True once the closing delimiter has been parsed (the rest is epilogue).
  bool done() const { return state_ == State::kEpilogue; }
  // Number of parts begun so far.
  std::size_t part_count() const { return part_count_; }

 private:
  enum class State {
    kPreamble,        // Looking for the first delimiter.
    kAfterDelimiter,  // Just after "--boundary": expecting "--" or padding + CRLF.
    kHeaders,         // Reading a part's header block.
    kBody,            // Streaming a part's content, looking for the next delimiter.
    kEpilogue,        // After the closing delimiter; input is ignored.
    kFailed,
  };

  // Runs the state machine over `buffer_` as far as it can; returns the first error.
  Status Process();
  Status ParseHeaders(std::string_view block);
  Status Fail(Status status);

  const std::string delimiter_;  // "\r\n--" + boundary.
  Callbacks callbacks_;
  Options options_;
  State state_ = State::kPreamble;
  // Unconsumed input; bounded by the largest chunk plus header/delimiter look-ahead.
  std::string buffer_;
  std::size_t part_count_ = 0;
  Status error_;
};

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_MULTIPART_H_
