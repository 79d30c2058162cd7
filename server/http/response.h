// The response a handler returns, and every error response of the server, built in one place.
//
// A Response is a transport-independent value: status, headers, and a body that is either a
// string or a file streamed from disk when the response is written. The transport
// (server/http/server.cc) adds the headers every response carries (Server, X-Request-Id,
// Content-Length, Connection) and a default Content-Type.
//
// Errors always have the JSON shape {"error": {"code": "not_found", "message": "..."}}; the
// `code` is a stable snake_case identifier clients can switch on, the message is for people.
//
//   return Response::Json({{"status", "ok"}});
//   return Response::FromStatus(Status::NotFound("job 42 does not exist"));   // 404 JSON error
//   return ErrorResponse(HttpStatus::conflict, "job is already finished");
#ifndef RECONDUIT_SERVER_HTTP_RESPONSE_H_
#define RECONDUIT_SERVER_HTTP_RESPONSE_H_

#include "core/util/status.h"

#include <boost/beast/http/status.hpp>
#include <nlohmann/json_fwd.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace reconduit::server {

using HttpStatus = boost::beast::http::status;

inline constexpr std::string_view kJsonContentType = "application/json";
inline constexpr std::string_view kTextContentType = "text/plain; charset=utf-8";

// A part of a file: `length` bytes starting at `offset`.
struct FileSlice {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
};

// One step of a streamed response body (see Response::Stream).
struct StreamStep {
  // Bytes to send now; may be empty.
  std::string data;
  // True when the body is complete after `data`.
  bool done = false;
};
// Produces the next piece of a streamed body. Called on an I/O thread: keep it short.
using StreamProducer = std::function<StreamStep()>;

class Response {
 public:
  // An empty 200 response.
  Response() = default;
  explicit Response(HttpStatus status) : status_(status) {}

  // `body` serialised compactly, Content-Type application/json.
  static Response Json(const nlohmann::json& body, HttpStatus status = HttpStatus::ok);
  static Response Text(std::string body,
                       HttpStatus status = HttpStatus::ok,
                       std::string_view content_type = kTextContentType);
  // A file sent from disk in pieces when the response is written (never loaded into memory).
  // The file is opened by the transport; if it cannot be opened then, the client gets a 404
  // JSON error instead. `content_type` defaults to the type guessed from the extension.
  static Response File(std::filesystem::path path, std::string_view content_type = {});
  // A body produced while it is being sent, for Server-Sent Events: the transport writes the
  // header (chunked transfer coding), then calls `producer` at once and again every
  // `poll_interval` until a step says done, the client goes away or the server shuts down.
  // Data is sent as soon as it is produced. An exception from the producer ends the body.
  // HEAD requests get the header only.
  static Response Stream(StreamProducer producer,
                         std::chrono::milliseconds poll_interval,
                         std::string_view content_type);

  HttpStatus status() const { return status_; }
  void set_status(HttpStatus status) { status_ = status; }

  // Replaces any header of the same name (case-insensitive).
  void SetHeader(std::string_view name, std::string_view value);
  // The value of the first header called `name`, or nullptr.
  const std::string* FindHeader(std::string_view name) const;
  const std::vector<std::pair<std::string, std::string>>& headers() const { return headers_; }

  const std::string& body() const { return body_; }
  void set_body(std::string body) { body_ = std::move(body); }
  // Set for file responses; the string body is then unused.
  const std::optional<std::filesystem::path>& file() const { return file_; }
  // For file responses: send only this part of the file (a 206 answer to a Range request; the
  // handler sets the status and Content-Range). The slice must lie inside the file; if the
  // file has shrunk by the time it is sent, the client gets a 404 JSON error instead.
  void set_file_slice(FileSlice slice) { file_slice_ = slice; }
  const std::optional<FileSlice>& file_slice() const { return file_slice_; }
  // Set for streamed responses.
  const StreamProducer& stream_producer() const { return stream_producer_; }
  std::chrono::milliseconds stream_poll_interval() const { return stream_poll_interval_; }

 private:
  HttpStatus status_ = HttpStatus::ok;
  std::vector<std::pair<std::string, std::string>> headers_;
  std::string body_;
  std::optional<std::filesystem::path> file_;
  std::optional<FileSlice> file_slice_;
  StreamProducer stream_producer_;
  std::chrono::milliseconds stream_poll_interval_{0};
};

// The stable error code for an HTTP status: 400 "bad_request", 401 "unauthorized",
// 404 "not_found", 405 "method_not_allowed", 409 "conflict", 413 "payload_too_large",
// 415 "unsupported_media_type", 429 "too_many_requests", 500 "internal", 503 "unavailable", ...
std::string_view DefaultErrorCode(HttpStatus status);

// {"error":{"code":code,"message":message}} with the given status. An empty `code` uses
// DefaultErrorCode(status).
Response ErrorResponse(HttpStatus status, std::string_view message, std::string_view code = {});

// 401 with `WWW-Authenticate: Bearer realm="reconduit"` (RFC 6750).
Response UnauthorizedResponse(std::string_view message);
// 405 with the `Allow` header listing the methods the path supports ("GET, HEAD").
Response MethodNotAllowedResponse(std::string_view allow);
// 429 or 503 with `Retry-After: <seconds>`.
Response RetryLaterResponse(HttpStatus status, std::string_view message, int retry_after_seconds);

// Maps a reconduit::Status code to the HTTP status a handler should answer with:
//   kInvalidArgument -> 400, kNotFound -> 404, kFailedPrecondition and kAlreadyExists -> 409,
//   kDegenerate -> 422 (valid input that cannot be reconstructed), kResourceExhausted -> 503
//   (server capacity: queue or disk full; sent with Retry-After), kCanceled -> 503,
//   kNotRun and kInternal -> 500, kOk -> 200.
HttpStatus HttpStatusFor(StatusCode code);

// The JSON error for a non-OK Status: status from HttpStatusFor, code = the StatusCode name in
// snake_case ("failed_precondition", ...; kInvalidArgument gives "bad_request" like every 400),
// message = status.message(). Internal errors (500) do not echo the message, which may describe
// server internals; the caller should log it. kResourceExhausted gets `Retry-After:
// retry_after_seconds`.
Response ResponseFromStatus(const Status& status, int retry_after_seconds = 5);

// The MIME type for a file name by its extension (".html" -> "text/html; charset=utf-8",
// ".glb" -> "model/gltf-binary", ...); "application/octet-stream" when unknown.
std::string_view MimeTypeForPath(std::string_view path);

}  // namespace reconduit::server

#endif  // RECONDUIT_SERVER_HTTP_RESPONSE_H_
