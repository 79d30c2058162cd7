#include "server/http/response.h"

#include "server/http/url.h"

#include <nlohmann/json.hpp>

#include <array>

namespace reconduit::server {

Response Response::Json(const nlohmann::json& body, HttpStatus status) {
  Response response(status);
  response.SetHeader("Content-Type", kJsonContentType);
  // Replace invalid UTF-8 rather than throwing: a message may quote client input.
  response.body_ = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  return response;
}

Response Response::Text(std::string body, HttpStatus status, std::string_view content_type) {
  Response response(status);
  response.SetHeader("Content-Type", content_type);
  response.body_ = std::move(body);
  return response;
}

Response Response::File(std::filesystem::path path, std::string_view content_type) {
  Response response(HttpStatus::ok);
  response.SetHeader("Content-Type", content_type.empty()
                                         ? MimeTypeForPath(path.filename().string())
                                         : content_type);
  response.file_ = std::move(path);
  return response;
}

Response Response::Stream(StreamProducer producer,
                          std::chrono::milliseconds poll_interval,
                          std::string_view content_type) {
  Response response(HttpStatus::ok);
  response.SetHeader("Content-Type", content_type);
  response.stream_producer_ = std::move(producer);
  response.stream_poll_interval_ = poll_interval;
  return response;
}

void Response::SetHeader(std::string_view name, std::string_view value) {
  for (auto& [key, existing] : headers_) {
    if (EqualsIgnoreCase(key, name)) {
      existing = std::string(value);
      return;
    }
  }
  headers_.emplace_back(std::string(name), std::string(value));
}

const std::string* Response::FindHeader(std::string_view name) const {
  for (const auto& [key, value] : headers_) {
    if (EqualsIgnoreCase(key, name)) return &value;
  }
  return nullptr;
}

std::string_view DefaultErrorCode(HttpStatus status) {
  switch (status) {
    case HttpStatus::bad_request:
      return "bad_request";
    case HttpStatus::unauthorized:
      return "unauthorized";
    case HttpStatus::forbidden:
      return "forbidden";
    case HttpStatus::not_found:
      return "not_found";
    case HttpStatus::method_not_allowed:
      return "method_not_allowed";
    case HttpStatus::request_timeout:
      return "request_timeout";
    case HttpStatus::conflict:
      return "conflict";
    case HttpStatus::length_required:
      return "length_required";
    case HttpStatus::payload_too_large:
      return "payload_too_large";
    case HttpStatus::uri_too_long:
      return "uri_too_long";
    case HttpStatus::unsupported_media_type:
      return "unsupported_media_type";
    case HttpStatus::range_not_satisfiable:
      return "range_not_satisfiable";
    case HttpStatus::unprocessable_entity:
      return "unprocessable_entity";
    case HttpStatus::too_many_requests:
      return "too_many_requests";
    case HttpStatus::request_header_fields_too_large:
      return "header_too_large";
    case HttpStatus::not_implemented:
      return "not_implemented";
    case HttpStatus::service_unavailable:
      return "unavailable";
    default:
      break;
  }
  const unsigned code = static_cast<unsigned>(status);
  if (code >= 500) return "internal";
  if (code >= 400) return "bad_request";
  return "error";
}

Response ErrorResponse(HttpStatus status, std::string_view message, std::string_view code) {
  const nlohmann::json body = {
      {"error",
       {{"code", std::string(code.empty() ? DefaultErrorCode(status) : code)},
        {"message", std::string(message)}}}};
  return Response::Json(body, status);
}

Response UnauthorizedResponse(std::string_view message) {
  Response response = ErrorResponse(HttpStatus::unauthorized, message);
  response.SetHeader("WWW-Authenticate", "Bearer realm=\"reconduit\"");
  return response;
}

Response MethodNotAllowedResponse(std::string_view allow) {
  Response response = ErrorResponse(HttpStatus::method_not_allowed,
                                    "method not allowed; this path supports " + std::string(allow));
  response.SetHeader("Allow", allow);
  return response;
}

Response RetryLaterResponse(HttpStatus status, std::string_view message, int retry_after_seconds) {
  Response response = ErrorResponse(status, message);
  response.SetHeader("Retry-After", std::to_string(retry_after_seconds));
  return response;
}

HttpStatus HttpStatusFor(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return HttpStatus::ok;
    case StatusCode::kInvalidArgument:
      return HttpStatus::bad_request;
    case StatusCode::kNotFound:
      return HttpStatus::not_found;
    case StatusCode::kFailedPrecondition:
    case StatusCode::kAlreadyExists:
      return HttpStatus::conflict;
    case StatusCode::kDegenerate:
      return HttpStatus::unprocessable_entity;
    case StatusCode::kResourceExhausted:
    case StatusCode::kCanceled:
      return HttpStatus::service_unavailable;
    case StatusCode::kNotRun:
    case StatusCode::kInternal:
      return HttpStatus::internal_server_error;
  }
  return HttpStatus::internal_server_error;
}

Response ResponseFromStatus(const Status& status, int retry_after_seconds) {
  const HttpStatus http_status = HttpStatusFor(status.code());
  if (status.ok()) return Response(http_status);
  // Every 400 says bad_request, whatever produced it (query parameters, options, bodies).
  const std::string code = status.code() == StatusCode::kInvalidArgument
                               ? std::string("bad_request")
                               : ToLowerAscii(StatusCodeName(status.code()));
  if (http_status == HttpStatus::internal_server_error) {
    return ErrorResponse(http_status, "internal server error", code);
  }
  Response response = ErrorResponse(http_status, status.message(), code);
  if (status.code() == StatusCode::kResourceExhausted) {
    response.SetHeader("Retry-After", std::to_string(retry_after_seconds));
  }
  return response;
}

std::string_view MimeTypeForPath(std::string_view path) {
  struct Entry {
    std::string_view extension;
    std::string_view type;
  };
  static constexpr std::array<Entry, 30> kTypes = {{
      {".html", "text/html; charset=utf-8"},
      {".htm", "text/html; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".txt", "text/plain; charset=utf-8"},
      {".svg", "image/svg+xml"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".gif", "image/gif"},
      {".webp", "image/webp"},
      {".ico", "image/vnd.microsoft.icon"},
      {".tif", "image/tiff"},
      {".tiff", "image/tiff"},
      {".wasm", "application/wasm"},
      {".woff2", "font/woff2"},
      {".glb", "model/gltf-binary"},
      {".gltf", "model/gltf+json"},
      {".ply", "application/octet-stream"},
      {".zip", "application/zip"},
      {".xml", "application/xml"},
      {".ndjson", "application/x-ndjson"},
      {".csv", "text/csv; charset=utf-8"},
      {".out", "text/plain; charset=utf-8"},
      {".obj", "model/obj"},
      {".mtl", "model/mtl"},
      {".bin", "application/octet-stream"},
  }};
  const std::size_t dot = path.rfind('.');
  if (dot != std::string_view::npos) {
    const std::string_view extension = path.substr(dot);
    for (const Entry& entry : kTypes) {
      if (EqualsIgnoreCase(entry.extension, extension)) return entry.type;
    }
  }
  return "application/octet-stream";
}

}  // namespace reconduit::server
